//! `sdctl weight`.

use crate::commands::model_json;
use crate::io::{emit, from_hinf, CliError};

#[derive(clap::Subcommand, Debug)]
pub(crate) enum WeightKind {
    /// PID-like: integrator, lead around the bandwidth, optional low-pass; |W/(m s²)| = 1 at the bandwidth.
    Pid {
        /// Bandwidth (Hz): |W/(m s²)| = 1 there.
        #[arg(long, allow_negative_numbers = true)]
        bandwidth_hz: f64,
        /// The plant's high-frequency mass line 1/(m s²): m in the plant's units.
        #[arg(long, allow_negative_numbers = true)]
        mass: f64,
        /// Sample period (s): a discrete weight (Tustin, prewarped); absent: continuous.
        #[arg(long, allow_negative_numbers = true)]
        ts: Option<f64>,
        /// Integrator corner at bandwidth / this ratio (0 removes the integrator).
        #[arg(long, default_value_t = 5.0, allow_negative_numbers = true)]
        integrator_ratio: f64,
        /// Lead zero at bandwidth / ratio, pole at bandwidth · ratio (≥ 1; 1 removes the lead).
        #[arg(long, default_value_t = 3.0, allow_negative_numbers = true)]
        lead_ratio: f64,
        /// 0: no low-pass.
        #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
        lowpass_ratio: f64,
        /// Damping of the optional second-order low-pass.
        #[arg(long, default_value_t = 0.7, allow_negative_numbers = true)]
        lowpass_zeta: f64,
        #[arg(help = crate::commands::OUTPUT_HELP, short, long)]
        output: Option<String>,
    },
    /// Notch (s² + 2ζz ω s + ω²)/(s² + 2ζp ω s + ω²), prewarped at its frequency.
    Notch {
        /// Notch frequency (Hz).
        #[arg(long, allow_negative_numbers = true)]
        freq_hz: f64,
        /// Damping of the zeros (the depth: ζz/ζp at the notch).
        #[arg(long, default_value_t = 0.01, allow_negative_numbers = true)]
        zeta_zero: f64,
        /// Damping of the poles (the width).
        #[arg(long, default_value_t = 0.2, allow_negative_numbers = true)]
        zeta_pole: f64,
        /// Sample period (s): a discrete weight (Tustin, prewarped); absent: continuous.
        #[arg(long, allow_negative_numbers = true)]
        ts: Option<f64>,
        #[arg(help = crate::commands::OUTPUT_HELP, short, long)]
        output: Option<String>,
    },
    /// Second-order low-pass ω²/(s² + 2ζω s + ω²), prewarped at its corner.
    Lowpass {
        /// Corner frequency (Hz).
        #[arg(long, allow_negative_numbers = true)]
        freq_hz: f64,
        /// Damping.
        #[arg(long, default_value_t = 0.7, allow_negative_numbers = true)]
        zeta: f64,
        /// Sample period (s): a discrete weight (Tustin, prewarped); absent: continuous.
        #[arg(long, allow_negative_numbers = true)]
        ts: Option<f64>,
        #[arg(help = crate::commands::OUTPUT_HELP, short, long)]
        output: Option<String>,
    },
    /// MATLAB-like makeweight: gain DC at low frequency, MAG at FREQ_HZ, HF at high
    /// frequency; order 1 or 2 (for S: DC small, HF > 1 is 1/|W|-style; the weight itself here).
    Makeweight {
        /// Low-frequency gain.
        #[arg(long, allow_negative_numbers = true)]
        dc: f64,
        /// Frequency (Hz) where the gain is MAG.
        #[arg(long, allow_negative_numbers = true)]
        freq_hz: f64,
        /// Gain at FREQ_HZ (strictly between DC and HF).
        #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
        mag: f64,
        /// High-frequency gain.
        #[arg(long, allow_negative_numbers = true)]
        hf: f64,
        /// 1 or 2.
        #[arg(long, default_value_t = 1)]
        order: usize,
        /// Sample period (s): a discrete weight (Tustin, prewarped at FREQ_HZ); absent: continuous.
        #[arg(long, allow_negative_numbers = true)]
        ts: Option<f64>,
        #[arg(help = crate::commands::OUTPUT_HELP, short, long)]
        output: Option<String>,
    },
}

/// Arguments of `sdctl weight`.
#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    #[command(subcommand)]
    pub(crate) kind: WeightKind,
}

impl Args {
    /// Runs the command.
    pub(crate) fn run(self) -> Result<(), CliError> {
        let Args { kind } = self;
        let (w, output) = match kind {
            WeightKind::Pid {
                bandwidth_hz,
                mass,
                ts,
                integrator_ratio,
                lead_ratio,
                lowpass_ratio,
                lowpass_zeta,
                output,
            } => {
                let opt = sd_hinf::weights::PidOptions {
                    integrator_ratio,
                    lead_ratio,
                    lowpass_ratio,
                    lowpass_zeta,
                };
                (sd_hinf::weights::pid(bandwidth_hz, mass, ts, &opt), output)
            }
            WeightKind::Notch {
                freq_hz,
                zeta_zero,
                zeta_pole,
                ts,
                output,
            } => (
                sd_hinf::weights::notch(freq_hz, zeta_zero, zeta_pole, ts),
                output,
            ),
            WeightKind::Lowpass {
                freq_hz,
                zeta,
                ts,
                output,
            } => (sd_hinf::weights::lowpass(freq_hz, zeta, ts), output),
            WeightKind::Makeweight {
                dc,
                freq_hz,
                mag,
                hf,
                order,
                ts,
                output,
            } => (
                sd_hinf::weights::makeweight(dc, freq_hz, mag, hf, order, ts),
                output,
            ),
        };
        let w = w.map_err(|e| from_hinf("weight", e))?;
        emit(&model_json(&w)?, output.as_deref())
    }
}
