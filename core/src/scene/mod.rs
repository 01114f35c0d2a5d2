//! Scenes shared by the CLI, the tests and the benches: defined once, here, one file per
//! family, each registered as a spec with parameters ([`register`]; `deepcontact list`
//! shows them):
//!
//! | spec | what | parameters (defaults) |
//! |---|---|---|
//! | `pile` | the thesis's circles in a box ([`pile_with`]) | `bodies` (100), `friction` (0.5) |
//! | `box-pile` | boxes of random size and aspect ([`box_pile`]) | `bodies` (100), `friction` (0.5) |
//! | `polygon-pile` | 3- to 8-gons mixed with circles ([`polygon_pile`]) | `bodies` (100), `friction` (0.5) |
//! | `pyramid` | unit boxes, a row fewer each level ([`pyramid_with`]) | `base` (10), `friction` (0.5), `jitter` (0 m) |
//! | `stack` | a tall stack of unit boxes ([`stack_with`]) | `count` (10), `friction` (0.5), `jitter` (0 m) |
//! | `ratio-stack` | a stack whose top box is `ratio` times heavier ([`ratio_stack`]) | `count` (5), `ratio` (100), `friction` (0.5), `jitter` (0 m) |
//! | `resting_ball` | one ball on the ground ([`resting_ball`]) | none |
//! | `thesis` | the original code's world of the seed ([`crate::scene_file::thesis_world`]) | none |
//! | `file` | circles from a scene file ([`crate::scene_file`]) | `path` |
//!
//! A seed places a pile's bodies and shifts the stacked boxes by up to `jitter`; the same
//! seed gives the same world, bit for bit.

mod pile;
mod small;
mod stacked;

pub use pile::{PileParams, ShapePileParams, box_pile, pile, pile_with, polygon_pile, walls};
pub use small::{resting_ball, slope};
pub use stacked::{StackParams, pyramid, pyramid_with, ratio_stack, stack, stack_with};

use crate::body::{BodyDesc, BodyKind};
use crate::error::CoreError;
use crate::math::{Real, Vector};
use crate::registry::{Params, Registry, SpecError};
use crate::world::{World, WorldSettings};

/// A named list of bodies plus the region they live in.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    /// Scene name (`"pile"`, `"pyramid"`, ...).
    pub name: String,
    /// Bodies in handle order.
    pub bodies: Vec<BodyDesc>,
    /// Lower corner of the region of interest (for rendering and grids).
    pub min: Vector,
    /// Upper corner of the region of interest.
    pub max: Vector,
}

impl Scene {
    /// Builds a world of this scene.
    pub fn build(&self, settings: WorldSettings) -> Result<World, CoreError> {
        World::with_bodies(settings, &self.bodies)
    }

    /// Number of dynamic bodies.
    pub fn dynamic_count(&self) -> usize {
        self.bodies
            .iter()
            .filter(|b| b.kind == BodyKind::Dynamic)
            .count()
    }
}

/// Names accepted by [`by_name`].
pub const SCENES: &[&str] = &[
    "pile",
    "box-pile",
    "polygon-pile",
    "pyramid",
    "stack",
    "ratio-stack",
    "resting_ball",
    "thesis",
    "file:PATH",
];

/// The most circles a pile may have: placement, memory (≈ 1 KB per body with its broad-phase
/// and solver data) and step time (≈ 25 ms per step at 10 000 bodies) grow with it, so a
/// larger request is refused at once instead of running for minutes.
pub const MAX_BODIES: usize = 1_000_000;

/// The largest base of a pyramid or height of a stack (a pyramid of 1 000 holds 500 500 boxes).
pub const MAX_STACK: usize = 1_000;

/// A scene by name with the other parameters at their defaults: `pile`, `box-pile`,
/// `polygon-pile` (use `seed` and `bodies`), `pyramid` (base of `bodies` boxes, 10 if
/// `bodies` is 100), `stack` (of `bodies` boxes, 10 if 100), `ratio-stack` (of `bodies`
/// boxes, 5 if 100), `resting_ball`, `thesis`
/// (the original code's world of `seed`), or `file:PATH`: the world of `seed` in the scene
/// file at `PATH` ([`crate::scene_file`] format) in the thesis's 15 m box.
pub fn by_name(name: &str, seed: u64, bodies: usize) -> Result<Scene, CoreError> {
    if let Some(path) = name.strip_prefix("file:") {
        let circles = crate::scene_file::load(path)?;
        return crate::scene_file::pile_from_circles(&circles, seed, 15.0, path);
    }
    let small = if bodies == 100 { 10 } else { bodies };
    // A pyramid of base b holds b (b + 1) / 2 boxes, a stack b: both bounded like the pile.
    if (name == "pyramid" || name == "stack" || name == "ratio-stack") && small > MAX_STACK {
        return Err(CoreError::InvalidSetting {
            name: "bodies",
            value: small as Real,
            reason: "is above the ceiling of 1 000 for pyramid and stack (MAX_STACK)",
        });
    }
    match name {
        "pile" => pile(seed, bodies),
        "box-pile" => box_pile(
            seed,
            &ShapePileParams {
                bodies,
                ..ShapePileParams::default()
            },
        ),
        "polygon-pile" => polygon_pile(
            seed,
            &ShapePileParams {
                bodies,
                ..ShapePileParams::default()
            },
        ),
        "ratio-stack" => ratio_stack(
            seed,
            &StackParams {
                count: if bodies == 100 { 5 } else { bodies },
                ..RATIO_STACK
            },
        ),
        "pyramid" => Ok(pyramid(small)),
        "stack" => Ok(stack(small)),
        "resting_ball" => Ok(resting_ball()),
        "thesis" => crate::scene_file::thesis_world(seed),
        _ => Err(CoreError::UnknownScene {
            name: name.to_string(),
            known: SCENES.join(", "),
        }),
    }
}

/// The mass-ratio stack's defaults: 5 boxes, the top one 100 times heavier.
const RATIO_STACK: StackParams = StackParams {
    count: 5,
    friction: 0.5,
    jitter: 0.0,
    ratio: 100.0,
};

/// A scene factory's error as a spec error naming the scene.
fn built(spec: &str, scene: Result<Scene, CoreError>) -> Result<Scene, SpecError> {
    scene.map_err(|e| SpecError::Build {
        spec: spec.to_string(),
        reason: e.to_string(),
    })
}

/// A count parameter (`usize`) with its default.
fn count(params: &mut Params<'_>, key: &'static str, default: usize) -> Result<usize, SpecError> {
    let v = params.u64(key, default as u64)?;
    usize::try_from(v).map_err(|_| params.invalid(key, &v.to_string(), "too large"))
}

/// Registers the scenes of the table in the [module docs](self).
pub fn register(registry: &mut Registry) {
    register_piles(registry);
    register_stacked(registry);
    registry.register_scene(
        "resting_ball",
        "one ball (r 0.5 m) resting on a ground box",
        |_, _| Ok(resting_ball()),
    );
    registry.register_scene(
        "thesis",
        "the original code's initial world of the seed (seeds 12345-12354 shipped)",
        |_, seed| built("thesis", crate::scene_file::thesis_world(seed)),
    );
    registry.register_scene(
        "file",
        "circles from a scene file in the thesis's 15 m box; path=FILE",
        |p, seed| {
            let path = p
                .string("path")
                .ok_or_else(|| p.invalid("path", "", "a scene file is required: file:path=FILE"))?
                .to_string();
            built(
                "file",
                crate::scene_file::load(&path).and_then(|circles| {
                    crate::scene_file::pile_from_circles(&circles, seed, 15.0, &path)
                }),
            )
        },
    );
}

/// `pile`, `box-pile` and `polygon-pile`.
fn register_piles(registry: &mut Registry) {
    registry.register_scene(
        "pile",
        "the thesis's circles (r 0.5 m) in a 15 m box scaled by sqrt(bodies/100); bodies=100, friction=0.5",
        |p, seed| {
            let bodies = count(p, "bodies", 100)?;
            let friction = p.f64("friction", 0.5)?;
            let material = crate::body::Material {
                friction,
                ..crate::body::Material::default()
            };
            built(
                "pile",
                pile::check_friction("friction", friction).and_then(|()| {
                    pile_with(
                        seed,
                        &PileParams {
                            bodies,
                            material,
                            wall_material: material,
                            ..PileParams::default()
                        },
                    )
                }),
            )
        },
    );
    for (name, help, make) in [
        (
            "box-pile",
            "boxes of random size (half-height 0.2-0.35 m) and aspect (1-2) in the pile's box; bodies=100, friction=0.5",
            box_pile as fn(u64, &ShapePileParams) -> Result<Scene, CoreError>,
        ),
        (
            "polygon-pile",
            "3- to 8-gons (r 0.35-0.55 m) mixed with circles (r 0.3-0.5 m) in the pile's box; bodies=100, friction=0.5",
            polygon_pile,
        ),
    ] {
        registry.register_scene(name, help, move |p, seed| {
            let params = ShapePileParams {
                bodies: count(p, "bodies", 100)?,
                friction: p.f64("friction", 0.5)?,
            };
            built(name, make(seed, &params))
        });
    }
}

/// `pyramid`, `stack` and `ratio-stack`.
fn register_stacked(registry: &mut Registry) {
    for (name, help, key, defaults, make) in [
        (
            "pyramid",
            "unit boxes on a ground box, base boxes at the bottom, one fewer per row; base=10, friction=0.5, jitter=0 (m, seeded sideways shift)",
            "base",
            StackParams::default(),
            pyramid_with as fn(u64, &StackParams) -> Result<Scene, CoreError>,
        ),
        (
            "stack",
            "a tall stack of unit boxes on a ground box; count=10, friction=0.5, jitter=0 (m, seeded sideways shift)",
            "count",
            StackParams::default(),
            stack_with,
        ),
        (
            "ratio-stack",
            "a stack of unit boxes whose top box is ratio times heavier; count=5, ratio=100, friction=0.5, jitter=0 (m)",
            "count",
            RATIO_STACK,
            ratio_stack,
        ),
    ] {
        registry.register_scene(name, help, move |p, seed| {
            let params = StackParams {
                count: count(p, key, defaults.count)?,
                friction: p.f64("friction", defaults.friction)?,
                jitter: p.f64("jitter", defaults.jitter)?,
                ratio: if name == "ratio-stack" {
                    p.f64("ratio", defaults.ratio)?
                } else {
                    defaults.ratio
                },
            };
            built(name, make(seed, &params))
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shape::ShapeDesc;

    fn registry() -> Registry {
        let mut r = Registry::empty();
        register(&mut r);
        r
    }

    /// Every body's state and shape as bits, to compare worlds exactly.
    fn bits(scene: &Scene) -> Vec<u64> {
        let world = scene.build(WorldSettings::default()).unwrap();
        world
            .bodies()
            .iter()
            .flat_map(|b| b.state())
            .map(f64::to_bits)
            .collect()
    }

    #[test]
    fn every_scene_is_the_same_world_for_the_same_seed_and_another_for_another() {
        let r = registry();
        for spec in [
            "pile:bodies=60",
            "box-pile:bodies=60",
            "polygon-pile:bodies=60",
            "pyramid:base=6,jitter=0.01",
            "stack:count=6,jitter=0.01",
            "ratio-stack:jitter=0.01",
        ] {
            let a = r.build_scene(spec, 7).unwrap();
            let b = r.build_scene(spec, 7).unwrap();
            let c = r.build_scene(spec, 8).unwrap();
            assert_eq!(bits(&a), bits(&b), "{spec}: same seed");
            assert_ne!(bits(&a), bits(&c), "{spec}: another seed");
        }
        // Without jitter the stacked scenes do not depend on the seed.
        let (a, b) = (
            r.build_scene("pyramid", 1).unwrap(),
            r.build_scene("pyramid", 2).unwrap(),
        );
        assert_eq!(bits(&a), bits(&b));
    }

    #[test]
    fn the_registered_pile_is_the_thesis_pile_bit_for_bit() {
        let r = registry();
        for seed in [12345, 3] {
            assert_eq!(
                bits(&r.build_scene("pile", seed).unwrap()),
                bits(&pile(seed, 100).unwrap())
            );
            assert_eq!(
                bits(&r.build_scene("pile:bodies=300", seed).unwrap()),
                bits(&by_name("pile", seed, 300).unwrap())
            );
        }
        assert_eq!(
            bits(&r.build_scene("pyramid:base=12", 0).unwrap()),
            bits(&pyramid(12))
        );
        assert_eq!(bits(&r.build_scene("stack", 0).unwrap()), bits(&stack(10)));
    }

    #[test]
    fn piles_hold_their_bodies_apart_and_inside_the_box() {
        let r = registry();
        for spec in ["box-pile:bodies=400", "polygon-pile:bodies=400"] {
            let scene = r.build_scene(spec, 12345).unwrap();
            assert_eq!(scene.dynamic_count(), 400, "{spec}");
            let radius = |shape: &ShapeDesc| match shape {
                ShapeDesc::Ball { radius } => *radius,
                ShapeDesc::Cuboid {
                    half_width,
                    half_height,
                } => half_width.hypot(*half_height),
                ShapeDesc::ConvexPolygon { vertices } => {
                    vertices.iter().map(|v| v.norm()).fold(0.0, Real::max)
                }
                other => panic!("unexpected shape {other:?}"),
            };
            let dynamic: Vec<&BodyDesc> = scene
                .bodies
                .iter()
                .filter(|b| b.kind == BodyKind::Dynamic)
                .collect();
            for (i, a) in dynamic.iter().enumerate() {
                let ra = radius(&a.shape);
                let inside = |x: Real| x - ra > 0.0 && x + ra < scene.max.x;
                assert!(
                    inside(a.position.x) && inside(a.position.y),
                    "{spec}: outside"
                );
                for b in &dynamic[..i] {
                    let d = (a.position - b.position).norm();
                    assert!(d >= ra + radius(&b.shape) - 1e-12, "{spec}: bodies overlap");
                }
            }
            // And the world accepts every shape.
            scene.build(WorldSettings::default()).unwrap();
        }
        // The polygon pile mixes circles with 3- to 8-gons.
        let scene = r.build_scene("polygon-pile:bodies=200", 1).unwrap();
        let mut sides = [0usize; 9];
        let mut circles = 0;
        for b in &scene.bodies {
            match &b.shape {
                ShapeDesc::ConvexPolygon { vertices } => sides[vertices.len()] += 1,
                ShapeDesc::Ball { .. } => circles += 1,
                _ => {}
            }
        }
        assert!(circles > 60 && circles < 140, "{circles} circles of 200");
        assert!(sides[3..=8].iter().all(|&n| n > 0), "{sides:?}");
    }

    #[test]
    fn box_and_polygon_piles_place_every_body_for_any_size_and_seed() {
        let r = registry();
        for name in ["box-pile", "polygon-pile"] {
            for bodies in [1, 2, 5, 20, 60, 100, 400] {
                for seed in 0..25 {
                    let spec = format!("{name}:bodies={bodies}");
                    let scene = r.build_scene(&spec, seed);
                    assert!(scene.is_ok(), "{spec} seed {seed}: {scene:?}");
                }
            }
        }
    }

    #[test]
    fn scene_parameters_reach_the_bodies() {
        let r = registry();
        let scene = r.build_scene("box-pile:bodies=20,friction=0.2", 1).unwrap();
        assert!(scene.bodies.iter().all(|b| b.material.friction == 0.2));
        let scene = r.build_scene("ratio-stack:count=4,ratio=30", 1).unwrap();
        let densities: Vec<Real> = scene.bodies[1..]
            .iter()
            .map(|b| b.material.density)
            .collect();
        assert_eq!(densities, [1.0, 1.0, 1.0, 30.0]);
        assert_eq!(
            r.build_scene("pyramid:base=20", 1).unwrap().dynamic_count(),
            210
        );
        // Jitter never makes neighbours of a row overlap (unit boxes: centres ≥ 1 m apart).
        for seed in 0..20 {
            let scene = r.build_scene("pyramid:base=8,jitter=0.05", seed).unwrap();
            let gaps: Vec<Real> = scene.bodies[1..]
                .windows(2)
                .filter(|w| w[0].position.y == w[1].position.y)
                .map(|w| w[1].position.x - w[0].position.x)
                .collect();
            assert_eq!(gaps.len(), 8 * 7 / 2, "seed {seed}");
            assert!(gaps.iter().all(|&g| g >= 1.0), "seed {seed}: {gaps:?}");
            assert!(gaps.iter().any(|&g| g != 1.1), "seed {seed}: no shift");
        }
    }

    #[test]
    fn bad_scene_specs_are_typed_errors() {
        let r = registry();
        assert!(matches!(
            r.build_scene("nosuch", 1),
            Err(SpecError::UnknownScene { .. })
        ));
        assert!(matches!(
            r.build_scene("pyramid:bodies=3", 1),
            Err(SpecError::UnknownParameter { .. })
        ));
        assert!(matches!(
            r.build_scene("stack:count=x", 1),
            Err(SpecError::InvalidParameter { .. })
        ));
        for bad in [
            "pile:friction=-1",
            "stack:count=0",
            "pyramid:jitter=0.5",
            "box-pile:bodies=0",
        ] {
            let err = r.build_scene(bad, 1).unwrap_err();
            assert!(matches!(err, SpecError::Build { .. }), "{bad}: {err}");
        }
    }
}
