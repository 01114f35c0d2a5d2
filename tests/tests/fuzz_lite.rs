//! "Fuzz-lite": the cargo-fuzz harnesses (`deepcontact-fuzz-harness`, `fuzz/harness/`) run on
//! stable under proptest, with random bytes and a few hand-written bad inputs, so that every
//! `cargo test` exercises them. The real fuzzers are described in `fuzz/README.md`.

use deepcontact_fuzz_harness::{
    Bytes, parse_specs, problem_from, scene_file, small_problem, solve_problem,
};
use proptest::prelude::*;

proptest! {
    #![proptest_config(ProptestConfig { cases: 1000, ..ProptestConfig::default() })]

    #[test]
    fn solve_problem_never_panics(data in prop::collection::vec(any::<u8>(), 0..400)) {
        solve_problem(&data);
    }

    #[test]
    fn parse_specs_never_panics(text in "[a-z_0-9:=,. \\-]{0,40}") {
        parse_specs(text.as_bytes());
    }

    #[test]
    fn parse_specs_never_panics_on_bytes(data in prop::collection::vec(any::<u8>(), 0..120)) {
        parse_specs(&data);
    }

    #[test]
    fn parse_specs_never_panics_on_known_names(
        name in prop::sample::select(vec!["none", "builtin", "random", "bad", "copy", "copy2", "copy0", "pgs", "psor", "newton",
            "extrapolate", "shock", "tail", "krylov", "best", "presolve", "sor", "graph", "graph-file", "learned-sor"]),
        key in prop::sample::select(vec!["seed", "normal_min", "normal_max", "tangent_max", "value", "normal", "tangent",
            "solver", "tolerance", "max_iterations", "decimals", "block", "order", "omega", "assembly",
            "dense_threshold", "reg", "alpha", "blend", "sweeps", "max_rate", "factor", "extrapolate",
            "iterations", "friction", "of", "rounds", "regularization", "on_failed_step", "backtracks",
            "stop_on_failed_step", "max_backtracks", "omega", "path", "card", "name", "start"]),
        value in prop::sample::select(vec!["0", "1", "-1", "nan", "inf", "-inf", "1e308", "-0", "2", "0.5",
            "true", "false", "pgs", "psor", "newton", "copy", "dense", "sparse", "18446744073709551616", "4294967296",
            "0.999", "builtin+none", "best", "nope+builtin", "stop", "retry", ""]),
    ) {
        parse_specs(format!("{name}:{key}={value}").as_bytes());
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, ..ProptestConfig::default() })]

    #[test]
    fn scene_file_never_panics_on_bytes(data in prop::collection::vec(any::<u8>(), 0..200)) {
        scene_file(&data);
    }

    #[test]
    fn scene_file_never_panics_on_near_valid_lines(
        side in any::<u8>(),
        lines in prop::collection::vec(
            "(0|1|-1),(0|7|18446744073709551616),[0-9]{1,3},(1|2.5|3|1e-300|1e300|nan|inf|-2|0x1),(1|2|5e-324|14.9|-0),(0.5|1|0|-1|1e-9|inf)",
            0..6,
        ),
    ) {
        let mut data = vec![side];
        data.extend(format!("world,seed,body_index,x,y,radius\n{}", lines.join("\n")).bytes());
        scene_file(&data);
    }
}

#[test]
fn a_valid_scene_file_steps_through_the_harness() {
    let mut data = vec![30u8];
    data.extend(b"world,seed,body_index,x,y,radius\n0,7,0,2,1,0.5\n0,7,1,2,2.2,0.5\n");
    scene_file(&data);
}

#[test]
fn the_byte_reader_produces_special_values() {
    let mut b = Bytes::new(&[0, 1, 2, 5, 9, 0xe8, 0x03]);
    assert!(b.real().is_nan());
    assert_eq!(b.real(), f64::INFINITY);
    assert_eq!(b.real(), f64::NEG_INFINITY);
    assert_eq!(b.real(), 1e300);
    assert_eq!(b.real(), 1.0);
    assert_eq!(b.byte(), 0, "zeros past the end");
}

#[test]
fn the_harness_builds_valid_and_invalid_problems() {
    let p = small_problem();
    p.validate().unwrap();
    assert_eq!((p.bodies.len(), p.len(), p.manifolds.len()), (3, 3, 2));
    // One static body at rest, then one op: a point of the body with itself, outside any
    // manifold. Invalid twice over, so `add_point` refuses it where it is made.
    let mut data = vec![0];
    data.extend([9, 0, 0].repeat(6));
    data.extend([0, 0, 1, 2, 0, 0, 1, 0, 0, 3, 3, 3, 3, 3, 3]);
    let p = problem_from(&mut Bytes::new(&data));
    assert_eq!((p.bodies.len(), p.len(), p.manifolds.len()), (1, 0, 0));
    assert!(p.validate().is_ok());
}

/// Hand-written bad inputs; each must be `Ok` or a typed error.
#[test]
fn known_bad_specs_do_not_panic() {
    for spec in [
        "",
        ":",
        "::",
        "random:",
        "random:seed",
        "random:seed=",
        "random:=1",
        "random:seed=1,seed=2",
        "random:normal_min=5,normal_max=1",
        "random:normal_max=nan",
        "random:normal_max=inf",
        "random:tangent_max=-1",
        "bad:value=nan",
        "bad:value=inf",
        "bad:normal=-1",
        "bad:value=1e308",
        "copy:solver=copy",
        "copy:solver=nope",
        "copy:tolerance=-1",
        "copy:tolerance=nan",
        "copy:max_iterations=0",
        "copy:decimals=400",
        "copy:decimals=18446744073709551615",
        "copy2:decimals=1",
        "pgs:block=maybe",
        "pgs:order=random",
        "psor:omega=2",
        "psor:omega=0",
        "psor:omega=nan",
        "psor:dense_threshold=0",
        "newton:reg=-1",
        "newton:reg=nan",
        "nope",
        "na me",
        "{\"format\": 1}",
        "{}",
        "[",
        "\u{0}",
        "é:ü=ß",
    ] {
        parse_specs(spec.as_bytes());
    }
}
