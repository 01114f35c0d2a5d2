//! Bad input to the command-line tool: every case must end with a non-zero exit status and one
//! clear line on stderr naming what was wrong — never a panic, never a backtrace.
//!
//! `cargo test -p deepcontact-cli --test bad_input -- --nocapture` prints the table of
//! docs/ROBUSTNESS.md (input, exit status, the message).

use std::path::{Path, PathBuf};
use std::process::Command;

/// A scratch directory under the target directory, emptied first.
fn scratch(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The repository's `models/` directory.
fn models() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../models")
}

struct Case {
    /// What is wrong, for the table.
    what: &'static str,
    args: Vec<String>,
    /// A fragment the message must contain (it names the field, file or value).
    expect: &'static str,
}

fn case(what: &'static str, args: &[&str], expect: &'static str) -> Case {
    Case {
        what,
        args: args.iter().map(|s| s.to_string()).collect(),
        expect,
    }
}

fn cases(dir: &Path) -> Vec<Case> {
    // Model files: missing, corrupt, card missing, card malformed, card of another model.
    // Cards without `model_sha256`, so that the backend itself meets the broken file.
    let card_text = std::fs::read_to_string(models().join("pressure.json")).unwrap();
    let mut card: serde_json::Value = serde_json::from_str(&card_text).unwrap();
    card.as_object_mut().unwrap().remove("model_sha256");
    let unpinned = serde_json::to_string_pretty(&card).unwrap();
    let garbage = dir.join("garbage.onnx");
    std::fs::write(&garbage, b"this is not a protobuf").unwrap();
    std::fs::write(dir.join("garbage.json"), &unpinned).unwrap();
    let no_card = dir.join("no_card.onnx");
    std::fs::copy(models().join("pressure.onnx"), &no_card).unwrap();
    let bad_card = dir.join("bad_card.onnx");
    std::fs::copy(models().join("pressure.onnx"), &bad_card).unwrap();
    std::fs::write(dir.join("bad_card.json"), b"{\"name\": \"pressure\", ").unwrap();
    let swapped = dir.join("swapped.onnx");
    std::fs::copy(models().join("peak.onnx"), &swapped).unwrap();
    std::fs::copy(models().join("pressure.json"), dir.join("swapped.json")).unwrap();
    let truncated = dir.join("truncated.onnx");
    let bytes = std::fs::read(models().join("pressure.onnx")).unwrap();
    std::fs::write(&truncated, &bytes[..bytes.len() / 2]).unwrap();
    std::fs::write(dir.join("truncated.json"), &unpinned).unwrap();
    let edited = dir.join("edited.onnx");
    let mut changed = bytes.clone();
    let last = changed.len() - 1;
    changed[last] ^= 1;
    std::fs::write(&edited, &changed).unwrap();
    std::fs::copy(models().join("pressure.json"), dir.join("edited.json")).unwrap();
    let onnx = |p: &Path| format!("onnx:path={}", p.display());
    let out = dir.join("out").display().to_string();
    let blocked = dir.join("blocked");
    std::fs::write(&blocked, b"a file where a directory should be").unwrap();
    let blocked = blocked.join("results").display().to_string();

    // Scene files (`--scene file:PATH`): each bad one names the file, the line and the field.
    let header = "world,seed,body_index,x,y,radius\n";
    let scene = |name: &str, text: &str| {
        let path = dir.join(name);
        std::fs::write(&path, text).unwrap();
        format!("file:{}", path.display())
    };
    let empty = scene("empty.csv", "");
    let cut = scene("truncated.csv", &format!("{header}0,7,0,2,1,0.5\n0,7,1,2"));
    let word = scene("word.csv", &format!("{header}0,7,0,two,1,0.5\n"));
    let inf = scene("inf.csv", &format!("{header}0,7,0,2,inf,0.5\n"));
    let overlapping = scene(
        "overlap.csv",
        &format!("{header}0,7,0,2,1,0.5\n0,7,1,2.5,1,0.5\n"),
    );
    let outside = scene("outside.csv", &format!("{header}0,7,0,20,1,0.5\n"));
    let huge_path = dir.join("huge.csv");
    // Sparse: 200 MiB on paper, nothing on disk.
    std::fs::File::create(&huge_path)
        .unwrap()
        .set_len(200 << 20)
        .unwrap();
    let huge = format!("file:{}", huge_path.display());
    let missing = format!("file:{}", dir.join("missing.csv").display());
    let other_seed = scene("seed7.csv", &format!("{header}0,7,0,2,1,0.5\n"));
    // The graph model: another file under its card, its file under a CNN's card.
    let graph_under_its_card = format!(
        "graph-file:path={},card={}",
        models().join("peak.onnx").display(),
        models().join("graph.json").display()
    );
    let graph_with_cnn_card = format!(
        "graph-file:path={},card={}",
        models().join("graph.safetensors").display(),
        models().join("pressure.json").display()
    );

    // The relaxation policy: a CNN card in its place.
    let policy_from_cnn_card = format!(
        "learned-sor:path={}",
        models().join("pressure.json").display()
    );

    fn sim<'a>(extra: &[&'a str]) -> Vec<&'a str> {
        let mut v = vec!["simulate", "--steps", "2"];
        v.extend_from_slice(extra);
        v
    }
    let list = vec![
        case(
            "unknown provider",
            &sim(&["--warm-start", "nosuch"]),
            "nosuch",
        ),
        case(
            "unknown provider parameter",
            &sim(&["--warm-start", "random:foo=1"]),
            "foo",
        ),
        case(
            "non-numeric parameter",
            &sim(&["--warm-start", "random:seed=abc"]),
            "abc",
        ),
        case(
            "over-relaxation factor out of range",
            &sim(&["--warm-start", "sor:omega=2"]),
            "[1, 2)",
        ),
        case(
            "graph model without a path",
            &sim(&["--warm-start", "graph-file"]),
            "needs path=",
        ),
        case(
            "graph model file missing",
            &sim(&["--warm-start", "graph-file:path=/nonexistent.safetensors"]),
            "/nonexistent.json",
        ),
        case(
            "another file under a graph card",
            &sim(&["--warm-start", &graph_under_its_card]),
            "is not the model of its card",
        ),
        case(
            "a CNN card for a graph model",
            &sim(&["--warm-start", &graph_with_cnn_card]),
            "not `deepcontact-graph-card`",
        ),
        case(
            "relaxation policy file missing",
            &sim(&["--warm-start", "learned-sor:path=/nonexistent.json"]),
            "/nonexistent.json",
        ),
        case(
            "a CNN card as a relaxation policy",
            &sim(&["--warm-start", &policy_from_cnn_card]),
            "missing field",
        ),
        case(
            "Newton-only presolve parameter with another solver",
            &sim(&["--warm-start", "presolve:solver=pgs,backtracks=3"]),
            "need solver=newton",
        ),
        case(
            "non-finite parameter",
            &sim(&["--warm-start", "bad:value=nan"]),
            "value",
        ),
        case(
            "negative random bound",
            &sim(&["--warm-start", "random:normal_max=-1"]),
            "normal_max",
        ),
        case(
            "unknown solver option",
            &sim(&["--solver", "pgs:order=weird"]),
            "weird",
        ),
        case(
            "PSOR relaxation out of (0, 2)",
            &sim(&["--solver", "psor:omega=2.5"]),
            "omega",
        ),
        case("negative tolerance", &sim(&["--tolerance=-1"]), "tolerance"),
        case(
            "zero iteration cap",
            &sim(&["--max-iterations", "0"]),
            "max_iterations",
        ),
        case(
            "negative linear slop",
            &sim(&["--linear-slop=-0.1"]),
            "slop",
        ),
        case(
            "non-finite prediction margin",
            &sim(&["--prediction", "inf"]),
            "prediction",
        ),
        case(
            "unknown scene",
            &sim(&["--scene", "nosuch"]),
            "unknown scene `nosuch`",
        ),
        case("empty pile", &sim(&["--bodies", "0"]), "bodies"),
        case(
            "model file missing",
            &sim(&["--warm-start", "onnx:path=/nonexistent/model.onnx"]),
            "not found",
        ),
        case(
            "model card missing",
            &sim(&["--warm-start", &onnx(&no_card)]),
            "card",
        ),
        case(
            "model card malformed JSON",
            &sim(&["--warm-start", &onnx(&bad_card)]),
            "card",
        ),
        case(
            "model file not ONNX",
            &sim(&["--warm-start", &onnx(&garbage)]),
            "garbage.onnx",
        ),
        case(
            "model file truncated",
            &sim(&["--warm-start", &onnx(&truncated)]),
            "truncated.onnx",
        ),
        case(
            "model file changed since its card (one bit)",
            &sim(&["--warm-start", &onnx(&edited)]),
            "SHA-256",
        ),
        case(
            "model and card of different models",
            &sim(&["--warm-start", &onnx(&swapped)]),
            "SHA-256",
        ),
        case(
            "reversed seed range",
            &["compare", "--seeds", "5..3", "--out", &out, "--no-plots"],
            "5..3",
        ),
        case(
            "output path under a file",
            &[
                "compare",
                "--seeds",
                "1",
                "--steps",
                "2",
                "--warm-starts",
                "none",
                "--out",
                &blocked,
                "--no-plots",
                "--quiet",
            ],
            "blocked",
        ),
        case(
            "a hundred million bodies (above the ceiling, refused at once)",
            &["simulate", "--bodies", "100000000", "--steps", "1"],
            "1 000 000",
        ),
        case(
            "a comparison too large for memory",
            &[
                "compare",
                "--steps",
                "100000000",
                "--out",
                &out,
                "--no-plots",
            ],
            "GiB",
        ),
        case(
            "a million threads",
            &[
                "compare",
                "--threads",
                "1000000",
                "--out",
                &out,
                "--no-plots",
            ],
            "threads",
        ),
        case(
            "solver threads: zero",
            &sim(&["--threads", "0"]),
            "--threads 0: must be 1 to 64",
        ),
        case(
            "solver threads: above the ceiling",
            &sim(&["--threads", "1000"]),
            "must be 1 to 64",
        ),
        case(
            "solver threads for a solver without them",
            &sim(&["--threads", "2", "--solver", "newton"]),
            "only the pgs solver",
        ),
        case(
            "solver threads twice, disagreeing",
            &sim(&["--threads", "2", "--solver", "pgs:threads=4"]),
            "disagrees",
        ),
        case(
            "solver spec threads=0",
            &sim(&["--solver", "pgs:threads=0"]),
            "threads",
        ),
        case(
            "solver spec domains=64",
            &sim(&["--solver", "pgs:domains=64"]),
            "must be 0 to 63",
        ),
        case("unknown preset", &sim(&["--preset", "nope"]), "preset"),
        case(
            "the suite with parameters",
            &[
                "compare",
                "--scenes",
                "suite:bodies=300",
                "--out",
                &out,
                "--no-plots",
            ],
            "`suite` takes no parameters",
        ),
        case(
            "a capped tolerance budget of 0",
            &[
                "compare",
                "--budgets",
                "tolerance@0",
                "--out",
                &out,
                "--no-plots",
            ],
            "tolerance@0",
        ),
        case(
            "bad shard",
            &["generate", "--shard", "4/4", "--out", &out, "--quiet"],
            "4/4",
        ),
        case("empty scene file", &sim(&["--scene", &empty]), "empty"),
        case(
            "truncated scene file",
            &sim(&["--scene", &cut, "--seed", "7"]),
            "line 3, field line",
        ),
        case(
            "non-numeric field in a scene file",
            &sim(&["--scene", &word, "--seed", "7"]),
            "line 2, field x",
        ),
        case(
            "non-finite field in a scene file",
            &sim(&["--scene", &inf, "--seed", "7"]),
            "line 2, field y",
        ),
        case(
            "overlapping circles in a scene file",
            &sim(&["--scene", &overlapping, "--seed", "7"]),
            "line 3, field x",
        ),
        case(
            "circle outside the box in a scene file",
            &sim(&["--scene", &outside, "--seed", "7"]),
            "line 2, field x",
        ),
        case(
            "huge scene file (200 MiB)",
            &sim(&["--scene", &huge, "--seed", "7"]),
            "MAX_FILE_BYTES",
        ),
        case(
            "missing scene file",
            &sim(&["--scene", &missing]),
            "missing.csv",
        ),
        case(
            "scene file without the requested seed",
            &sim(&["--scene", &other_seed, "--seed", "8"]),
            "seed 8",
        ),
        case(
            "a hundred million round-trip worlds (hung before the ceiling)",
            &["grid-roundtrip", "--worlds", "100000000", "--out", &out],
            "ceiling",
        ),
    ];
    list
}

#[test]
fn every_bad_input_gets_one_clear_line_and_a_non_zero_exit() {
    let dir = scratch("bad_input");
    let mut table = String::from("| bad input | command | exit | message |\n|---|---|---:|---|\n");
    let mut failures = Vec::new();
    for c in cases(&dir) {
        let out = Command::new(env!("CARGO_BIN_EXE_deepcontact"))
            .args(&c.args)
            .env("RUST_BACKTRACE", "1")
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        let lines: Vec<&str> = stderr.lines().filter(|l| !l.trim().is_empty()).collect();
        let message = lines.last().copied().unwrap_or("").to_string();
        let shown: Vec<String> = c
            .args
            .iter()
            .map(|a| a.replace(&dir.display().to_string(), "$TMP"))
            .collect();
        table.push_str(&format!(
            "| {} | `{}` | {} | {} |\n",
            c.what,
            shown.join(" "),
            out.status.code().map_or("signal".into(), |c| c.to_string()),
            message
                .replace(&dir.display().to_string(), "$TMP")
                .replace('|', "\\|")
        ));
        let ok = !out.status.success()
            && lines.len() == 1
            && !stderr.contains("panicked")
            && !stderr.contains("stack backtrace")
            && message.contains(c.expect);
        if !ok {
            failures.push(format!(
                "{}: status {:?}, {} lines on stderr:\n{stderr}",
                c.what,
                out.status,
                lines.len()
            ));
        }
    }
    println!("{table}");
    assert!(failures.is_empty(), "{}", failures.join("\n---\n"));
}
