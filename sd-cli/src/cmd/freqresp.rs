//! `sdctl freqresp`.

use crate::commands::parse_grid;
use crate::io::{emit_parts, from_model, read_model, CliError};

/// Arguments of `sdctl freqresp`.
#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    #[arg(help = crate::commands::MODEL_HELP)]
    pub(crate) model: String,
    /// Frequencies `FMIN:FMAX:N[:log]` in Hz (at most the Nyquist frequency of a discrete model).
    #[arg(long)]
    pub(crate) grid: String,
    /// Also write the response as CSV to this file: per entry and frequency the magnitude
    /// (dB) and unwrapped phase (degrees).
    #[arg(long)]
    pub(crate) csv: Option<String>,
    #[arg(help = crate::commands::OUTPUT_HELP, short, long)]
    pub(crate) output: Option<String>,
}

impl Args {
    /// Runs the command.
    pub(crate) fn run(self) -> Result<(), CliError> {
        let Args {
            model,
            grid,
            csv,
            output,
        } = self;
        let sys = read_model(&model)?;
        let f = parse_grid(&grid)?;
        if let Some(ny) = sys.time().nyquist_hz() {
            if let Some(fm) = f.iter().cloned().reduce(f64::max) {
                if fm > ny * (1.0 + 1e-12) {
                    return Err(CliError::input(format!("--grid {grid}: FMAX = {fm} Hz is above the model's Nyquist frequency {ny} Hz")));
                }
            }
        }
        let ev = sd_model::FreqRespEvaluator::new(&sys).map_err(|e| from_model(&model, e))?;
        // which algorithm ran (the block-diagonal form unless it failed its accuracy check)
        let (key, words) = match ev.path() {
            sd_model::EvalPath::BlockDiagonal => {
                ("block_diagonal", "block-diagonal (O(n) per point)")
            }
            sd_model::EvalPath::Hessenberg => ("hessenberg", "Hessenberg (O(n²) per point)"),
            sd_model::EvalPath::Dense => ("dense", "dense LU (O(n³) per point)"),
        };
        eprintln!(
            "[freqresp] {} states, {} points, path: {words}",
            sys.n(),
            f.len()
        );
        // one flat buffer evaluated in parallel, formatted in parallel chunks and written
        // chunk by chunk (no matrix per point, no single copy of the document)
        let mut flat = ev.eval_many_flat(&f);
        ev.mark_poles(&f, &mut flat);
        // a point at a pole has an infinite response ([`sd_model::FreqRespEvaluator::eval_at`]),
        // which JSON cannot hold
        let m = (sys.ny() * sys.nu()).max(1);
        if let Some(k) = flat
            .iter()
            .position(|v| !(v.re.is_finite() && v.im.is_finite()))
        {
            return Err(CliError::input(format!(
                "{model}: {} Hz is a pole of the model (its response is infinite there); leave that frequency out of the grid",
                f[k / m]
            )));
        }
        if let Some(path) = &csv {
            let (ny, nu) = (sys.ny(), sys.nu());
            let resp = (0..f.len())
                .map(|k| nalgebra::DMatrix::from_fn(ny, nu, |o, i| flat[k * ny * nu + i * ny + o]))
                .collect();
            let frd = sd_model::Frd::new(f.clone(), resp, None, sys.time())
                .map_err(|e| from_model(&model, e))?;
            crate::io::emit(crate::io::frd_csv(&frd).trim_end(), Some(path))?;
        }
        // the FRD object gains `"eval_path"` (informational, ignored by the readers)
        let chunks = sd_model::frd_json_chunks(
            &f,
            (sys.ny(), sys.nu()),
            &flat,
            sys.time().ts(),
            &format!(",\"eval_path\":\"{key}\""),
        )
        .map_err(|e| from_model(&model, e))?;
        let parts: Vec<&[u8]> = chunks.iter().map(Vec::as_slice).collect();
        emit_parts(&parts, output.as_deref())
    }
}
