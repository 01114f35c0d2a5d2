//! Piles from files of circle positions, and the original thesis worlds compiled in.
//!
//! **Format** (CSV, a header line, then one line per circle):
//! `world,seed,body_index,x,y,radius` — `world` groups the circles of one scene (any integer),
//! `seed` names it (the seed that placed it), `body_index` orders the circles within it
//! (creation order; need not be contiguous), `x`, `y` the centre in metres inside the box
//! `[0, side]²`, `radius` in metres (> 0). Circles of one world must not overlap and must lie
//! inside the box. Every error names the file, the line and the field.
//!
//! [`thesis_world`] loads `core/data/thesis_worlds_initial.csv`: the exact float32 initial
//! positions of the ten comparison worlds (seeds 12345–12354) as the original code
//! (LukasEngedal/Deep-Contact, modified pybox2d) created them.

use crate::body::{BodyDesc, Material};
use crate::error::CoreError;
use crate::math::{Real, Vector};
use crate::scene::{Scene, walls};
use crate::shape::ShapeDesc;

/// The original's ten comparison worlds (see the [module](self) docs).
pub const THESIS_WORLDS_CSV: &str = include_str!("../data/thesis_worlds_initial.csv");

/// The header every scene file starts with.
pub const HEADER: &str = "world,seed,body_index,x,y,radius";

/// One circle of a scene file.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FileCircle {
    /// Scene number.
    pub world: i64,
    /// Seed the scene is known by.
    pub seed: u64,
    /// Creation order within the scene.
    pub body_index: u64,
    /// Centre (m).
    pub centre: Vector,
    /// Radius (m).
    pub radius: Real,
    /// Line of the file it was read from (1 = the header; 0 for circles built in code).
    pub line: usize,
}

/// The largest scene file read (128 MiB: a million circles take about 60 MB), checked
/// before reading so that a wrong path to a huge file fails at once.
pub const MAX_FILE_BYTES: u64 = 128 << 20;

/// Reads the scene file at `path` (at most [`MAX_FILE_BYTES`]) and parses it.
pub fn load(path: &str) -> Result<Vec<FileCircle>, CoreError> {
    let err = |reason: String| CoreError::SceneFile {
        file: path.to_string(),
        line: 0,
        field: "file".into(),
        reason,
    };
    let size = std::fs::metadata(path)
        .map_err(|e| err(e.to_string()))?
        .len();
    if size > MAX_FILE_BYTES {
        return Err(err(format!(
            "{size} bytes, above the ceiling of {MAX_FILE_BYTES} bytes (scene_file::MAX_FILE_BYTES)"
        )));
    }
    let text = std::fs::read_to_string(path).map_err(|e| err(e.to_string()))?;
    parse(&text, path)
}

/// Parses a scene file's text; `file` names it in errors.
pub fn parse(text: &str, file: &str) -> Result<Vec<FileCircle>, CoreError> {
    let err = |line: usize, field: &str, reason: String| CoreError::SceneFile {
        file: file.to_string(),
        line,
        field: field.to_string(),
        reason,
    };
    let mut lines = text.lines().enumerate();
    match lines.next() {
        Some((_, h)) if h.trim() == HEADER => {}
        Some((_, h)) => {
            return Err(err(
                1,
                "header",
                format!("expected `{HEADER}`, found `{h}`"),
            ));
        }
        None => return Err(err(0, "header", "the file is empty".into())),
    }
    let mut out = Vec::new();
    for (i, line) in lines {
        let n = i + 1;
        if line.trim().is_empty() {
            continue;
        }
        let cols: Vec<&str> = line.split(',').map(str::trim).collect();
        if cols.len() != 6 {
            return Err(err(n, "line", format!("{} fields, expected 6", cols.len())));
        }
        let names = ["world", "seed", "body_index", "x", "y", "radius"];
        let int = |k: usize| {
            cols[k]
                .parse::<i64>()
                .map_err(|e| err(n, names[k], format!("`{}`: {e}", cols[k])))
        };
        let uint = |k: usize| {
            cols[k]
                .parse::<u64>()
                .map_err(|e| err(n, names[k], format!("`{}`: {e}", cols[k])))
        };
        let real = |k: usize| match cols[k].parse::<Real>() {
            Ok(v) if v.is_finite() => Ok(v),
            Ok(v) => Err(err(n, names[k], format!("{v} is not finite"))),
            Err(e) => Err(err(n, names[k], format!("`{}`: {e}", cols[k]))),
        };
        let circle = FileCircle {
            world: int(0)?,
            seed: uint(1)?,
            body_index: uint(2)?,
            centre: Vector::new(real(3)?, real(4)?),
            radius: real(5)?,
            line: n,
        };
        if circle.radius <= 0.0 {
            return Err(err(n, "radius", format!("{} must be > 0", circle.radius)));
        }
        if out.len() == crate::scene::MAX_BODIES {
            return Err(err(
                n,
                "line",
                format!(
                    "more than {} circles (scene::MAX_BODIES)",
                    crate::scene::MAX_BODIES
                ),
            ));
        }
        out.push(circle);
    }
    if out.is_empty() {
        return Err(err(0, "world", "no circle in the file".into()));
    }
    Ok(out)
}

/// The pile of the circles of `circles` with seed `seed`, in `body_index` order, in the
/// thesis box of side `side` (walls first, as [`crate::scene::pile`]); circles checked to lie
/// inside the box and not to overlap.
pub fn pile_from_circles(
    circles: &[FileCircle],
    seed: u64,
    side: Real,
    file: &str,
) -> Result<Scene, CoreError> {
    let err = |line: usize, field: &str, reason: String| CoreError::SceneFile {
        file: file.to_string(),
        line,
        field: field.to_string(),
        reason,
    };
    let mut mine: Vec<&FileCircle> = circles.iter().filter(|c| c.seed == seed).collect();
    if mine.is_empty() {
        let mut seeds: Vec<u64> = circles.iter().map(|c| c.seed).collect();
        seeds.sort_unstable();
        seeds.dedup();
        return Err(err(
            0,
            "seed",
            format!("no world with seed {seed} (the file has {seeds:?})"),
        ));
    }
    mine.sort_by_key(|c| c.body_index);
    for c in &mine {
        let (p, r) = (c.centre, c.radius);
        let outside = |v: Real| v < r || v > side - r;
        if let Some((field, v)) = [("x", p.x), ("y", p.y)]
            .into_iter()
            .find(|&(_, v)| outside(v))
        {
            return Err(err(
                c.line,
                field,
                format!(
                    "circle {} at ({}, {}) with radius {r} is not inside the box [0, {side}]² ({field} = {v})",
                    c.body_index, p.x, p.y
                ),
            ));
        }
    }
    if let Some((a, b)) = first_overlap(&mine) {
        return Err(err(
            b.line,
            "x",
            format!(
                "circle {} overlaps circle {} (line {})",
                b.body_index, a.body_index, a.line
            ),
        ));
    }
    let mut bodies = walls(side, Material::default());
    bodies.extend(mine.iter().map(|c| {
        BodyDesc::dynamic(ShapeDesc::Ball { radius: c.radius }, c.centre)
            .with_material(Material::default())
    }));
    Ok(Scene {
        name: "thesis".into(),
        bodies,
        min: Vector::zeros(),
        max: Vector::new(side, side),
    })
}

/// Two circles that overlap (by more than 1e-9 m), the later in `circles`' order second, or
/// none. Sweep and prune along x: after sorting by left edge, a circle can only overlap those
/// whose left edge lies before its right edge, so the check is O(n log n) for a pile (a
/// million circles in well under a second) instead of comparing every pair.
fn first_overlap<'a>(circles: &[&'a FileCircle]) -> Option<(&'a FileCircle, &'a FileCircle)> {
    let mut order: Vec<usize> = (0..circles.len()).collect();
    order.sort_by(|&a, &b| {
        let left = |k: usize| circles[k].centre.x - circles[k].radius;
        left(a).total_cmp(&left(b))
    });
    let mut found: Option<(usize, usize)> = None;
    for (k, &i) in order.iter().enumerate() {
        let ci = circles[i];
        for &j in &order[k + 1..] {
            let cj = circles[j];
            if cj.centre.x - cj.radius >= ci.centre.x + ci.radius {
                break;
            }
            if (cj.centre - ci.centre).norm() < ci.radius + cj.radius - 1e-9 {
                let pair = (i.min(j), i.max(j));
                // Report the pair whose later circle comes first, as a scan in order would.
                if found.is_none_or(|f| (pair.1, pair.0) < (f.1, f.0)) {
                    found = Some(pair);
                }
            }
        }
    }
    found.map(|(a, b)| (circles[a], circles[b]))
}

/// The original code's initial world for `seed` (12345 to 12354), in its 15 × 15 m box.
///
/// ```
/// let scene = deepcontact_core::scene_file::thesis_world(12345).unwrap();
/// assert_eq!(scene.bodies.len(), 4 + 100);
/// assert!(deepcontact_core::scene_file::thesis_world(7).is_err());
/// ```
pub fn thesis_world(seed: u64) -> Result<Scene, CoreError> {
    let circles = parse(THESIS_WORLDS_CSV, "<embedded thesis worlds>")?;
    pile_from_circles(&circles, seed, 15.0, "<embedded thesis worlds>")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_files_name_the_line_and_field() {
        let e = |t: &str| parse(t, "f.csv").unwrap_err().to_string();
        assert!(e("").contains("empty"));
        assert!(e("x,y\n").contains("header"));
        let h = format!("{HEADER}\n");
        assert!(e(&format!("{h}1,2,3,4\n")).contains("line 2, field line"));
        assert!(e(&format!("{h}1,2,3,abc,1,0.5\n")).contains("field x"));
        assert!(e(&format!("{h}1,2,3,1,inf,0.5\n")).contains("field y"));
        assert!(e(&format!("{h}1,2,3,1,1,-0.5\n")).contains("field radius"));
        assert!(e(&h).contains("no circle"));
        let two = parse(&format!("{h}1,9,1,5,5,0.5\n1,9,2,5.5,5,0.5\n"), "f.csv").unwrap();
        let overlap = pile_from_circles(&two, 9, 15.0, "f.csv")
            .unwrap_err()
            .to_string();
        assert!(overlap.contains("overlap"), "{overlap}");
        assert!(overlap.contains("line 3, field x"), "{overlap}");
        assert!(overlap.contains("(line 2)"), "{overlap}");
        let out = parse(&format!("{h}1,9,1,5,0.2,0.5\n"), "f.csv").unwrap();
        let outside = pile_from_circles(&out, 9, 15.0, "f.csv")
            .unwrap_err()
            .to_string();
        assert!(outside.contains("line 2, field y"), "{outside}");
        assert!(
            pile_from_circles(&out, 8, 15.0, "f.csv")
                .unwrap_err()
                .to_string()
                .contains("seed 8")
        );
    }

    /// The sweep-and-prune overlap check against every pair, on seeded random circles.
    #[test]
    fn overlap_check_agrees_with_all_pairs() {
        let mut rng = crate::rng::PortableRng::new(11);
        for case in 0..200 {
            let n = 1 + case % 40;
            let circles: Vec<FileCircle> = (0..n)
                .map(|k| FileCircle {
                    world: 0,
                    seed: 1,
                    body_index: k as u64,
                    centre: Vector::new(rng.uniform_range(0.0, 10.0), rng.uniform_range(0.0, 10.0)),
                    radius: rng.uniform_range(0.05, 0.3 + 0.02 * (case % 7) as Real),
                    line: k + 2,
                })
                .collect();
            let refs: Vec<&FileCircle> = circles.iter().collect();
            let brute = (0..n)
                .flat_map(|b| (0..b).map(move |a| (a, b)))
                .find(|&(a, b)| {
                    let (ca, cb) = (&circles[a], &circles[b]);
                    (ca.centre - cb.centre).norm() < ca.radius + cb.radius - 1e-9
                });
            let swept = first_overlap(&refs).map(|(a, b)| (a.line - 2, b.line - 2));
            assert_eq!(
                swept.map(|p| p.1),
                brute.map(|p| p.1),
                "case {case}: the same later circle"
            );
            assert_eq!(swept.is_some(), brute.is_some(), "case {case}");
        }
    }

    #[test]
    fn a_scene_file_loads_by_name() {
        let path = std::env::temp_dir().join(format!("dc_scene_{}.csv", std::process::id()));
        std::fs::write(&path, THESIS_WORLDS_CSV).unwrap();
        let name = format!("file:{}", path.display());
        let from_file = crate::scene::by_name(&name, 12347, 100).unwrap();
        let embedded = thesis_world(12347).unwrap();
        assert_eq!(from_file.bodies.len(), embedded.bodies.len());
        for (a, b) in from_file.bodies.iter().zip(&embedded.bodies) {
            assert_eq!(a.position, b.position);
        }
        std::fs::remove_file(&path).unwrap();
        let missing = crate::scene::by_name(&name, 12347, 100)
            .unwrap_err()
            .to_string();
        assert!(missing.contains(&path.display().to_string()), "{missing}");
    }

    #[test]
    fn the_ten_thesis_worlds_load() {
        for seed in 12345..12355 {
            let s = thesis_world(seed).unwrap();
            assert_eq!(s.bodies.len(), 104);
        }
    }
}
