//! Draws a world (bodies, walls, contact normals) to a PNG.

use std::path::Path;

use deepcontact_core::math::rotate;
use deepcontact_core::{BodyKind, World};
use plotters::prelude::*;

use crate::ExperimentError;

/// Renders the bodies, walls and last step's contact normals of `world` to `path` (PNG,
/// written to a temporary file and renamed). Dynamic bodies are blue outlines with a radius
/// line showing their angle, static bodies black, contact normals short red segments.
pub fn render_world(world: &World, path: &Path) -> Result<(), ExperimentError> {
    let plot_err = |e: &dyn std::fmt::Display| ExperimentError::Plot {
        path: path.display().to_string(),
        reason: e.to_string(),
    };
    let outline = |b: &deepcontact_core::Body| -> Vec<(f64, f64)> {
        let mut pts: Vec<(f64, f64)> = b
            .shape_desc
            .outline(32)
            .iter()
            .map(|v| {
                let p = b.origin() + rotate(v, b.angle);
                (p.x, p.y)
            })
            .collect();
        if b.shape_desc.is_solid() && !pts.is_empty() {
            pts.push(pts[0]);
        }
        pts
    };
    let (mut lo, mut hi) = (
        (f64::INFINITY, f64::INFINITY),
        (f64::NEG_INFINITY, f64::NEG_INFINITY),
    );
    for b in world.bodies() {
        for (x, y) in outline(b) {
            lo = (lo.0.min(x), lo.1.min(y));
            hi = (hi.0.max(x), hi.1.max(y));
        }
    }
    if !(lo.0.is_finite() && hi.0.is_finite()) {
        (lo, hi) = ((0.0, 0.0), (1.0, 1.0));
    }
    let span = (hi.0 - lo.0).max(hi.1 - lo.1).max(1e-3) * 1.04;
    let (cx, cy) = (0.5 * (lo.0 + hi.0), 0.5 * (lo.1 + hi.1));
    let tmp = path.with_extension("tmp.png");
    {
        let root = BitMapBackend::new(&tmp, (900, 900)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| plot_err(&e))?;
        let mut chart = ChartBuilder::on(&root)
            .margin(10)
            .build_cartesian_2d(
                (cx - 0.5 * span)..(cx + 0.5 * span),
                (cy - 0.5 * span)..(cy + 0.5 * span),
            )
            .map_err(|e| plot_err(&e))?;
        for b in world.bodies() {
            let (colour, width) = match b.kind {
                BodyKind::Dynamic => (BLUE, 1),
                BodyKind::Kinematic => (GREEN, 2),
                BodyKind::Static => (BLACK, 3),
            };
            chart
                .draw_series(std::iter::once(PathElement::new(
                    outline(b),
                    colour.stroke_width(width),
                )))
                .map_err(|e| plot_err(&e))?;
            if b.kind == BodyKind::Dynamic {
                let tip = b.position
                    + rotate(
                        &deepcontact_core::Vector::new(b.shape_desc.bounding_radius(), 0.0),
                        b.angle,
                    );
                chart
                    .draw_series(std::iter::once(PathElement::new(
                        vec![(b.position.x, b.position.y), (tip.x, tip.y)],
                        colour.mix(0.5).stroke_width(1),
                    )))
                    .map_err(|e| plot_err(&e))?;
            }
        }
        let normals = world.raw_contacts().iter().map(|c| {
            let q = c.point + 0.25 * c.normal;
            PathElement::new(
                vec![(c.point.x, c.point.y), (q.x, q.y)],
                RED.stroke_width(2),
            )
        });
        chart.draw_series(normals).map_err(|e| plot_err(&e))?;
        root.present().map_err(|e| plot_err(&e))?;
    }
    std::fs::rename(&tmp, path).map_err(|e| ExperimentError::Io {
        path: path.display().to_string(),
        source: e,
    })?;
    Ok(())
}
