//! The markdown tables the scaling example prints.

use crate::ours::Totals;
use crate::peer::PeerRow;
use crate::phases::Phases;

/// Everything measured for one pile size.
pub struct SizeRow {
    /// Bodies.
    pub bodies: usize,
    /// The fixed-iteration setting on the settled pile.
    pub fixed: Totals,
    /// The thesis stop rule on the settled pile, if run.
    pub thesis: Option<Totals>,
    /// The phases of a fixed step.
    pub phases: Phases,
}

/// The fixed and thesis settings, per size.
pub fn steps(rows: &[SizeRow], iterations: u32) {
    println!(
        "| bodies | contacts | fixed {iterations}: ms/step (min) | solve ms | rest ms | ns/contact/iter | \
         µs/contact/step | thesis: ms/step | iterations (max) |"
    );
    println!("|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for r in rows {
        let f = &r.fixed;
        let contacts = f.mean_contacts();
        let (t_ms, t_it) = r.thesis.as_ref().map_or(("–".into(), "–".into()), |t| {
            (
                format!("{:.2}", t.ms(t.wall)),
                format!("{:.0}", t.iterations_max as f64 / t.steps.max(1) as f64),
            )
        });
        println!(
            "| {} | {contacts:.0} | {:.2} ({:.2}) | {:.2} | {:.2} | {:.1} | {:.2} | {t_ms} | {t_it} |",
            r.bodies,
            f.ms(f.wall),
            f.wall_min * 1e3,
            f.ms(f.solve),
            f.ms(f.wall - f.solve - f.warm),
            f.ns_per_point_iteration(),
            f.ms(f.wall) * 1e3 / contacts.max(1.0),
        );
    }
}

/// The phases of a fixed step, per size.
pub fn phases(rows: &[SizeRow], iterations: u32) {
    println!(
        "\nPhases of a fixed-{iterations} step, timed one by one on the settled world (minimum over \
         repetitions; ns per contact point; velocity and position per point-iteration):\n"
    );
    println!(
        "| bodies | contacts | pairs | broad | narrow | islands | velocity /it | position /it | position its | \
         min step ms |"
    );
    println!("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for r in rows {
        let (ph, f) = (&r.phases, &r.fixed);
        let contacts = f.mean_contacts();
        let per = |s: f64| s / contacts.max(1.0) * 1e9;
        println!(
            "| {} | {contacts:.0} | {} | {:.0} | {:.0} | {:.0} | {:.1} | {:.1} | {:.1} | {:.2} |",
            r.bodies,
            ph.pairs,
            per(ph.broad),
            per(ph.narrow),
            per(ph.islands),
            per(ph.velocity) / f64::from(iterations),
            per(ph.position) / ph.position_iterations.max(1.0),
            ph.position_iterations,
            f.wall_min * 1e3,
        );
    }
}

/// The peer comparison: ns per solver contact point per pass, ours beside each rapier2d
/// configuration, with the ratios ours / rapier2d of the same process.
pub fn peer(rows: &[PeerRow], passes: u32) {
    let Some(first) = rows.first() else {
        return;
    };
    println!(
        "\nVelocity solve, ns per solver contact point per pass, {passes} passes per step (ours: PGS \
         iterations, normal and friction rows; rapier2d: its velocity resolution divided by all its \
         passes, PGS and stabilisation); ratio = ours / rapier2d; points = mean solver contact \
         points per step; ms = whole step:\n"
    );
    let mut head = String::from("| bodies | pile | steps | ours ns | points | ms |");
    let mut rule = String::from("|---:|---|---:|---:|---:|---:|");
    for (config, _) in &first.rapier {
        head += &format!(" {} ns | ratio | points | ms |", config.label());
        rule += "---:|---:|---:|---:|";
    }
    println!("{head}\n{rule}");
    for r in rows {
        let mut line = format!(
            "| {} | {} | {} | {:.2} | {:.0} | {:.2} |",
            r.bodies, r.pile, r.steps, r.ours.ns, r.ours.points, r.ours.step_ms
        );
        for (_, c) in &r.rapier {
            line += &format!(
                " {:.2} | {:.2} | {:.0} | {:.2} |",
                c.ns,
                r.ours.ns / c.ns,
                c.points,
                c.step_ms
            );
        }
        println!("{line}");
    }
}
