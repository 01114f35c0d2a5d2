//! The command line of the scaling example.

/// What to run.
pub struct Options {
    /// Pile sizes.
    pub sizes: Vec<usize>,
    /// Velocity iterations of the `fixed` setting.
    pub iterations: u32,
    /// Passes per step of the peer comparison (ours: PGS iterations; rapier2d: see
    /// `RapierConfig`).
    pub passes: u32,
    /// Steps of the whole-run peer comparison (from the initial state).
    pub run_steps: u64,
    /// Settling steps (default: [`settle_steps`]).
    pub settle: Option<u64>,
    /// Velocity cap while settling.
    pub settle_cap: u32,
    /// Steps measured per setting (default: [`measure_steps`]).
    pub measure: Option<u64>,
    /// Run rapier2d beside ours.
    pub rapier: bool,
    /// Run the whole-run peer comparison.
    pub whole_run: bool,
    /// Run the thesis stop rule on the settled pile.
    pub thesis: bool,
    /// Rounds of the slope measurement (0: none).
    pub slope_rounds: u32,
    /// Steps per engine, pass count and round of the slope (default: `slope::block_steps`).
    pub slope_block: Option<u64>,
    /// Print progress while settling.
    pub trace: bool,
}

const USAGE: &str = "scaling [--sizes 100,1000,10000] [--iterations 10] [--passes 100] \
                     [--run-steps 250] [--settle STEPS] [--settle-cap 50] [--measure STEPS] \
                     [--slope-rounds 15] [--slope-block STEPS] [--no-rapier] [--no-run] \
                     [--no-thesis] [--trace]";

/// Parses the command line (`None`: help was printed).
pub fn parse() -> Result<Option<Options>, String> {
    let mut o = Options {
        sizes: deepcontact_benches::SIZES.to_vec(),
        iterations: 10,
        passes: 100,
        run_steps: 250,
        settle: None,
        settle_cap: 50,
        measure: None,
        rapier: true,
        whole_run: true,
        thesis: true,
        slope_rounds: 15,
        slope_block: None,
        trace: false,
    };
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut value = || args.next().ok_or(format!("{a} needs a value"));
        match a.as_str() {
            "--sizes" => o.sizes = list(&value()?, &a)?,
            "--iterations" => o.iterations = number(&value()?, &a)?,
            "--passes" => o.passes = number(&value()?, &a)?,
            "--run-steps" => o.run_steps = number(&value()?, &a)?,
            "--settle" => o.settle = Some(number(&value()?, &a)?),
            "--settle-cap" => o.settle_cap = number(&value()?, &a)?,
            "--measure" => o.measure = Some(number(&value()?, &a)?),
            "--slope-rounds" => o.slope_rounds = number(&value()?, &a)?,
            "--slope-block" => o.slope_block = Some(number(&value()?, &a)?),
            "--no-rapier" => o.rapier = false,
            "--no-run" => o.whole_run = false,
            "--no-thesis" => o.thesis = false,
            "--trace" => o.trace = true,
            "-h" | "--help" => {
                println!("{USAGE}");
                return Ok(None);
            }
            other => return Err(format!("unknown argument {other}\n{USAGE}")),
        }
    }
    Ok(Some(o))
}

fn number<T: std::str::FromStr>(s: &str, flag: &str) -> Result<T, String>
where
    T::Err: std::fmt::Display,
{
    s.trim().parse().map_err(|e| format!("{flag}: {e}"))
}

fn list(s: &str, flag: &str) -> Result<Vec<usize>, String> {
    s.split(',').map(|v| number(v, flag)).collect()
}

/// Steps to settle a pile of `n` bodies: 250 × (n / 100)^¼.
pub fn settle_steps(n: usize) -> u64 {
    (250.0 * (n as f64 / 100.0).powf(0.25)).round() as u64
}

/// Steps measured per setting: about 50 000 body-steps, 5 to 500.
pub fn measure_steps(n: usize) -> u64 {
    (50_000 / n as u64).clamp(5, 500)
}
