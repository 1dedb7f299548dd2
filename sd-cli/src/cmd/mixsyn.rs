//! `sdctl mixsyn`.

use super::hinfsyn::report_json;
use crate::commands::{finite_pos, model_json};
use crate::io::{emit, from_hinf, read_model, CliError};
use sd_model::StateSpace;

/// Arguments of `sdctl mixsyn`.
#[derive(clap::Args, Debug)]
pub(crate) struct Args {
    /// Plant model JSON (discrete or continuous).
    pub(crate) plant: String,
    /// Weight on the sensitivity S (ny×ny model JSON).
    #[arg(long)]
    pub(crate) w1: Option<String>,
    /// Weight on the control sensitivity KS (nu×nu).
    #[arg(long)]
    pub(crate) w2: Option<String>,
    /// Weight on the complementary sensitivity T (ny×ny).
    #[arg(long)]
    pub(crate) w3: Option<String>,
    /// Input (force) disturbance shaping (nu×nu): adds the process sensitivity SG; needed when
    /// the plant has poles on the stability boundary (a rigid body).
    #[arg(long)]
    pub(crate) wd: Option<String>,
    /// Multirate design: PLANT is the fast model at h and the controller runs at T = F·h,
    /// sampling the error at the slow instants and holding its output; every weight acts at
    /// the fast rate and the error between the samples counts (the lifted plant,
    /// `sd_hinf::multirate`). Without --wr there is no reference: disturbance rejection.
    #[arg(long)]
    pub(crate) factor: Option<usize>,
    /// With --factor: the smooth reference's shaping r = W_r r̃ (ny×ny, fast rate).
    #[arg(long)]
    pub(crate) wr: Option<String>,
    /// With --factor: the sensor noise's gain at the slow samples (the same on every
    /// measurement).
    #[arg(long, allow_negative_numbers = true)]
    pub(crate) wn: Option<f64>,
    /// With --factor: the effort weight on the controller's samples (nu×nu, discrete at T),
    /// instead of or beside --w2 on the held control at every fast sample.
    #[arg(long)]
    pub(crate) w2_slow: Option<String>,
    /// With --factor: W₁'s extra factor at the controller's sample instants (above 1 the
    /// error at the samples counts more than between them).
    #[arg(long, allow_negative_numbers = true)]
    pub(crate) at_samples: Option<f64>,
    /// Design at this γ (at least γ_min) instead of at γ_min.
    #[arg(long, allow_negative_numbers = true)]
    pub(crate) gamma: Option<f64>,
    /// Relative tolerance of the γ iteration.
    #[arg(long, default_value_t = sd_hinf::tol::GAMMA_TOL, allow_negative_numbers = true)]
    pub(crate) tol: f64,
    /// Print gamma, gamma_min, achieved_norm and the controller as JSON.
    #[arg(long)]
    pub(crate) json: bool,
    #[arg(help = crate::commands::OUTPUT_HELP, short, long)]
    pub(crate) output: Option<String>,
}

impl Args {
    /// Runs the command.
    pub(crate) fn run(self) -> Result<(), CliError> {
        let g = read_model(&self.plant)?;
        let read = |p: &Option<String>| -> Result<Option<StateSpace>, CliError> {
            p.as_deref().map(read_model).transpose()
        };
        let (w1, w2, w3, wd) = (
            read(&self.w1)?,
            read(&self.w2)?,
            read(&self.w3)?,
            read(&self.wd)?,
        );
        let tol = finite_pos(self.tol, "--tol")?;
        if let Some(gm) = self.gamma {
            finite_pos(gm, "--gamma")?;
        }
        let w = sd_hinf::MixsynWeights {
            w1: w1.as_ref(),
            w2: w2.as_ref(),
            w3: w3.as_ref(),
            wd: wd.as_ref(),
        };
        let opt = sd_hinf::HinfOptions {
            gamma: self.gamma,
            tolerance: tol,
            ..Default::default()
        };
        let (r, p, extra) = match self.factor {
            None => {
                if self.wr.is_some()
                    || self.wn.is_some()
                    || self.w2_slow.is_some()
                    || self.at_samples.is_some()
                {
                    return Err(CliError::input(
                        "--wr, --wn, --w2-slow and --at-samples belong to a multirate design: \
                         give --factor F",
                    ));
                }
                let (r, p) =
                    sd_hinf::mixsyn(&g, &w, &opt).map_err(|e| from_hinf(&self.plant, e))?;
                (
                    r,
                    p,
                    vec![("convention", "u = K (r − y) (negative feedback)".into())],
                )
            }
            Some(f) => self.multirate(&g, f, w, &opt)?,
        };
        let controller = model_json(&r.controller)?;
        if self.json {
            let mut extra = extra;
            extra.push(("generalized_plant_states", p.n().into()));
            let v = report_json(&r, &controller, extra)?;
            emit(&v, self.output.as_deref())
        } else {
            eprintln!(
                "γ_min {:.6}, γ {:.6}, achieved {:.6}, closed loop {}, controller order {} \
                 (use as u = K (r − y))",
                r.gamma_min,
                r.gamma,
                r.achieved_norm,
                if r.closed_loop_stable {
                    "stable"
                } else {
                    "UNSTABLE"
                },
                r.controller_order
            );
            emit(&controller, self.output.as_deref())
        }
    }

    /// The multirate design (`--factor`).
    fn multirate(
        &self,
        g: &StateSpace,
        factor: usize,
        mix: sd_hinf::MixsynWeights<'_>,
        opt: &sd_hinf::HinfOptions,
    ) -> Result<(sd_hinf::HinfSynthesis, StateSpace, Extra), CliError> {
        if factor == 0 {
            return Err(CliError::input("--factor must be at least 1 (T = F·h)"));
        }
        let wr = self.wr.as_deref().map(read_model).transpose()?;
        let w2s = self.w2_slow.as_deref().map(read_model).transpose()?;
        let wn = match self.wn {
            Some(v) if !v.is_finite() => {
                return Err(CliError::input(format!("--wn {v}: give a finite number")))
            }
            Some(v) => Some(nalgebra::DMatrix::identity(g.ny(), g.ny()) * v),
            None => None,
        };
        let w = sd_hinf::MultirateWeights {
            mix,
            wr: wr.as_ref(),
            wn: wn.as_ref(),
            w2_slow: w2s.as_ref(),
            at_samples: self.at_samples,
        };
        let r = sd_hinf::multirate_hinfsyn(g, factor, &w, opt)
            .map_err(|e| from_hinf(&self.plant, e))?;
        let rms = sd_hinf::multirate_rms(g, factor, &w, &r.synthesis.controller)
            .map_err(|e| from_hinf(&self.plant, e))?;
        let extra: Extra = vec![
            ("factor", factor.into()),
            (
                "predicted_rms",
                serde_json::to_value(&rms).map_err(|e| CliError::numerical(e.to_string()))?,
            ),
            (
                "convention",
                "u_k = K m_k at T = F·h, m_k = e(kF) the sampled error (negative feedback), \
                 u held over the F fast samples"
                    .into(),
            ),
        ];
        Ok((r.synthesis, r.plant, extra))
    }
}

/// Extra JSON keys of the report.
type Extra = Vec<(&'static str, serde_json::Value)>;
