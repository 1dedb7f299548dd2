//! `sdctl downsample`.

use crate::cmd::uncertainty::{from_unc, read_bound};
use crate::commands::{factor_arg, model_json};
use crate::io::{emit, from_multirate, read_model, CliError};

/// Arguments of `sdctl downsample`.
#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// Discrete model JSON file ("-" for stdin).
    pub(crate) model: String,
    /// Rate factor F = T/h (integer >= 1).
    #[arg(long, allow_negative_numbers = true)]
    pub(crate) factor: i64,
    /// Slow hold switching this fraction of the slow period late (a multiple of 1/F).
    #[arg(long, allow_negative_numbers = true)]
    pub(crate) hold_delay: Option<f64>,
    /// Slow sampler returning the mean of the last fraction of fast samples (a multiple of 1/F).
    #[arg(long, allow_negative_numbers = true)]
    pub(crate) averaging: Option<f64>,
    /// Uncertainty JSON of the fast model (`sdctl uncertainty`): its bound is downsampled too
    /// (Lemma 6 in the frequency domain: each slow line sums its F fold components weighted by
    /// the slow hold, and by the delay and averaging when given) and written to
    /// --uncertainty-out.
    #[arg(long, requires = "uncertainty_out")]
    pub(crate) uncertainty: Option<String>,
    /// Where the slow-rate uncertainty JSON goes (its lines: the fast bound's lines below the
    /// slow Nyquist frequency). Without --uncertainty, a model file that carries its bound
    /// (`sdctl uncertainty --embed`) gives a slow model carrying the downsampled bound.
    #[arg(long, requires = "uncertainty")]
    pub(crate) uncertainty_out: Option<String>,
    #[arg(help = crate::commands::OUTPUT_HELP, short, long)]
    pub(crate) output: Option<String>,
}

impl Args {
    /// Runs the command.
    pub(crate) fn run(self) -> Result<(), CliError> {
        let Args {
            model,
            factor,
            hold_delay,
            averaging,
            uncertainty,
            uncertainty_out,
            output,
        } = self;
        let sys = read_model(&model)?;
        if sys.ts().is_none() {
            return Err(CliError {
                code: 2,
                message: format!(
                    "{model}: downsample takes a discrete model at the fast rate (Lemma 6), and \
                     this one is continuous-time (\"ts\": null); for the slow model use \
                     `sdctl c2d {model} --ts <slow period>` directly (exact ZOH; --hold-delay and \
                     --averaging are there too), or c2d to the fast rate first"
                ),
            });
        }
        let f = factor_arg(factor)?;
        let ni = sd_multirate::NonIdeal {
            hold_delay: hold_delay.unwrap_or(0.0),
            averaging: averaging.unwrap_or(0.0),
        };
        let d = sd_multirate::downsample_nonideal(&sys, f, ni)
            .map_err(|e| from_multirate(&model, e))?;
        let mut text = model_json(&d)?;
        if let (Some(u), Some(out)) = (uncertainty, uncertainty_out) {
            let slow = slow_bound(&sys, f, ni, &u)?;
            let t = sd_uncertainty::to_json_string(&slow, None).map_err(|e| from_unc(&out, e))?;
            emit(&t, Some(&out))?;
        } else if model != "-" && sd_uncertainty::carries(&crate::io::read_text(&model)?) {
            // the model carries its bound: the slow model carries the downsampled one
            let slow = slow_bound(&sys, f, ni, &model)?;
            text = sd_uncertainty::embed(&text, &slow, None).map_err(|e| from_unc(&model, e))?;
        }
        emit(&text, output.as_deref())
    }
}

/// The fast bound in file `u` (an uncertainty JSON, or a model carrying one) of `sys`,
/// downsampled by `f` through the same hold and sampler as the model.
fn slow_bound(
    sys: &sd_model::StateSpace,
    f: usize,
    ni: sd_multirate::NonIdeal,
    u: &str,
) -> Result<sd_uncertainty::Bound, CliError> {
    let b = read_bound(u)?;
    // the bound must belong to this model: its nominal is the model's response
    let p = sys
        .freqresp(&b.freq_hz)
        .map_err(|e| crate::io::from_model(u, e))?;
    let off = p
        .response()
        .iter()
        .zip(&b.nominal)
        .map(|(m, n)| (m[(0, 0)] - n).norm() / n.norm().max(f64::MIN_POSITIVE))
        .fold(0.0, f64::max);
    if off > 1e-6 {
        return Err(CliError::input(format!(
            "{u}: its nominal response differs from the model's by {off:.1e} (relative): the \
             bound belongs to another model"
        )));
    }
    let d = sd_uncertainty::downsample_nonideal_all(&b, f, ni).map_err(|e| from_unc(u, e))?;
    eprintln!(
        "[downsample] uncertainty: {} slow lines ({} without all their folds on the fast grid)",
        d.bound.freq_hz.len(),
        d.missing_hz.len()
    );
    Ok(d.bound)
}
