//! McFarlane–Glover H∞ loopshaping, discrete time first (continuous time as well).
//!
//! Shaped plant `G_s = W₂ P W₁`. The robust stabilization problem of its normalized coprime
//! factors: find K_s minimizing `‖[I; K_s](I + G_s K_s)⁻¹[I  G_s]‖∞`; the optimum is
//! `γ_min = sqrt(1 + ρ(XZ))` (McFarlane & Glover 1990; Skogestad & Postlethwaite §9.4).
//!
//! **Discrete time.** γ_min comes from the discrete Riccati equations
//! (`X = dare(A, B, CᵀC, I)`, `Z = dare(Aᵀ, Cᵀ, BBᵀ, I)` for D = 0; with D ≠ 0 the standard
//! `R = I + DᵀD`, `S = CᵀD` forms). The central controller is obtained through the exact
//! bilinear map `z = (1 + s)/(1 − s)`: it maps the unit circle onto the imaginary axis, so the
//! 4-block norm, γ_min and stability are the same for `Ĝ(s) = G_s((1 + s)/(1 − s))`, which is
//! solved with the continuous formulas (S&P (9.66)–(9.68), with D):
//! `R = I + DᵀD`, `S = I + DDᵀ`, `X = care(A, B, CᵀC, R, CᵀD)`, `Z = care(Aᵀ, Cᵀ, BBᵀ, S, BDᵀ)`,
//! `F = −R⁻¹(DᵀC + BᵀX)`, `L = (1 − γ²)I + XZ`,
//! `K = [A + BF + γ²L⁻ᵀZCᵀ(C + DF), γ²L⁻ᵀZCᵀ; BᵀX, −Dᵀ]` (positive feedback), and mapped back
//! by `s = (z − 1)/(z + 1)`. The map carries the stabilizing Riccati solutions over unchanged
//! (`X_c = X_d`, `Z_c = Z_d`), so the DARE solutions are reused and checked by their CARE
//! residuals; an ill-conditioned problem whose residuals exceed 1e-10 has its CAREs solved and
//! both routes' γ_min checked against each other.
//! A shaped plant with D ≠ 0 is handled by the same formulas; a pole at z = −1 (which the
//! bilinear map sends to infinity) is refused.
//!
//! **Strictly proper variant** (no feedthrough, room for a one-sample computation delay):
//! every strictly proper K is `z⁻¹K'` with K' proper, and since `z⁻¹` is unitary on the unit
//! circle, `‖[I; z⁻¹K'](I + G K)⁻¹[I  G]‖ = ‖[I; K'](I + G'K')⁻¹[I  G']‖` with `G' = G z⁻¹`.
//! So the optimal strictly proper design is the central design for `G'` followed by a delay;
//! its γ_min is `γ_min(G')` ≥ `γ_min(G)`.
//!
//! **Sign conventions.** Everything returned is for **negative feedback**: `u = −K_s y` around
//! `G_s`, `u = −K y` around P, with `K = W₁ K_s W₂`.

pub use crate::bilinear::{bilinear_to_continuous, bilinear_to_discrete};
use crate::error::{HinfError, Result};
use crate::riccati::{care, care_residual_of, dare, RiccatiSolution};
use nalgebra::DMatrix;
use sd_model::connect::{feedback, series};
use sd_model::linalg::convert::eigenvalues;
use sd_model::{SampleTime, StateSpace};

/// Options of [`loopshape`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoopshapeOptions {
    /// γ = factor·γ_min; must be > 1 (1.1 is the classical choice).
    pub factor: f64,
    /// Discrete time only: a strictly proper controller (D_k = 0).
    pub strictly_proper: bool,
}

impl Default for LoopshapeOptions {
    fn default() -> Self {
        LoopshapeOptions {
            factor: 1.1,
            strictly_proper: false,
        }
    }
}

/// Residuals of the Riccati equations solved for a design.
#[derive(Debug, Clone)]
pub struct RiccatiReport {
    /// Which equation.
    pub name: String,
    /// Its relative residual.
    pub residual: f64,
    /// Its condition estimate (NaN for a CARE residual of the reused DARE solution: that
    /// solution's estimate is the DARE's entry).
    pub condition: f64,
}

/// A loopshaping design.
#[derive(Debug, Clone)]
pub struct Loopshape {
    /// The optimal robustness level of the shaped plant (of `G_s z⁻¹` when strictly proper).
    pub gamma_min: f64,
    /// γ = factor·γ_min, the level the controller is designed for.
    pub gamma: f64,
    /// The 4-block H∞ norm the shaped controller achieves (≤ γ).
    pub achieved: f64,
    /// `G_s = W₂ P W₁`.
    pub shaped_plant: StateSpace,
    /// `K_s` for negative feedback around `G_s`.
    pub shaped_controller: StateSpace,
    /// `K = W₁ K_s W₂` for negative feedback around P.
    pub controller: StateSpace,
    /// Whether P with K (negative feedback) is internally stable.
    pub closed_loop_stable: bool,
    /// Spectral radius (DT) or abscissa (CT) of that closed loop.
    pub closed_loop_radius: f64,
    /// The Riccati equations solved, with residuals.
    pub riccati: Vec<RiccatiReport>,
}

fn report(name: &str, s: &RiccatiSolution) -> RiccatiReport {
    RiccatiReport {
        name: name.into(),
        residual: s.residual,
        condition: s.condition,
    }
}

fn unit_gain(n: usize, time: SampleTime) -> Result<StateSpace> {
    Ok(StateSpace::gain(DMatrix::identity(n, n), time)?)
}

/// The data of the two Riccati equations of the normalized coprime factors of `gs`:
/// `(Q = CᵀC, R = I + DᵀD, S_x = CᵀD)` for X and `(BBᵀ, I + DDᵀ, S_z = BDᵀ)` for Z (the latter
/// on the dual `(Aᵀ, Cᵀ)`).
struct CoprimeData {
    q: DMatrix<f64>,
    r: DMatrix<f64>,
    cross_x: DMatrix<f64>,
    bbt: DMatrix<f64>,
    s: DMatrix<f64>,
    cross_z: DMatrix<f64>,
}

impl CoprimeData {
    fn new(gs: &StateSpace) -> Self {
        let (b, c, d) = (gs.b(), gs.c(), gs.d());
        let (nu, ny) = (gs.nu(), gs.ny());
        CoprimeData {
            q: c.transpose() * c,
            r: DMatrix::<f64>::identity(nu, nu) + d.transpose() * d,
            cross_x: c.transpose() * d,
            bbt: b * b.transpose(),
            s: DMatrix::<f64>::identity(ny, ny) + d * d.transpose(),
            cross_z: b * d.transpose(),
        }
    }
}

/// γ_min of a shaped plant from its own-domain Riccati equations, with the solutions.
pub fn gamma_min(gs: &StateSpace) -> Result<(f64, RiccatiSolution, RiccatiSolution)> {
    let (a, b, c) = (gs.a(), gs.b(), gs.c());
    let k = CoprimeData::new(gs);
    let solve = if gs.time().is_continuous() {
        care
    } else {
        dare
    };
    // the two equations are independent: one on each core
    let at = a.transpose();
    let ct = c.transpose();
    let (x, z) = rayon::join(
        || solve(a, b, &k.q, &k.r, Some(&k.cross_x)),
        || solve(&at, &ct, &k.bbt, &k.s, Some(&k.cross_z)),
    );
    let (x, z) = (x?, z?);
    Ok((gamma_of(&x.x, &z.x)?, x, z))
}

/// `γ_min = sqrt(1 + ρ(XZ))`.
fn gamma_of(x: &DMatrix<f64>, z: &DMatrix<f64>) -> Result<f64> {
    let rho = eigenvalues(&(x * z))?
        .iter()
        .map(|e| e.norm())
        .fold(0.0, f64::max);
    Ok((1.0 + rho).sqrt())
}

/// The continuous Riccati solutions of the bilinear image `gc` of a discrete shaped plant,
/// with their reports. The exact bilinear map with the √2 scaling carries the stabilizing
/// solutions over unchanged (`X_c = X_d`, `Z_c = Z_d`: the stable invariant subspace of the
/// Hamiltonian is the Cayley image of the symplectic pencil's stable deflating subspace, and
/// both are the graph of the same X), so the DARE solutions are checked by their residuals in
/// the CAREs (O(n³) products instead of two ordered Schur forms of order 2n; the test
/// `loopshaping::discrete_design_reuses_the_dare_solutions` measures `‖X_c − X_d‖/‖X_c‖` on the
/// 60-state stage with a PID weight: 1.4e-15). When a residual
/// exceeds [`crate::tol::BILINEAR_RESIDUAL`] (an ill-conditioned problem), the CAREs are solved
/// and γ_min from both routes must agree within [`crate::tol::GAMMA_AGREE`].
fn continuous_solutions(
    gc: &StateSpace,
    gm: f64,
    x: &RiccatiSolution,
    z: &RiccatiSolution,
) -> Result<(DMatrix<f64>, DMatrix<f64>, Vec<RiccatiReport>)> {
    let (a, b, c) = (gc.a(), gc.b(), gc.c());
    let k = CoprimeData::new(gc);
    let rx = care_residual_of(a, b, &k.q, &k.r, Some(&k.cross_x), &x.x)?;
    let at = a.transpose();
    let rz = care_residual_of(&at, &c.transpose(), &k.bbt, &k.s, Some(&k.cross_z), &z.x)?;
    if rx <= crate::tol::BILINEAR_RESIDUAL && rz <= crate::tol::BILINEAR_RESIDUAL {
        let reused = |name: &str, residual: f64| RiccatiReport {
            name: name.into(),
            residual,
            condition: f64::NAN,
        };
        return Ok((
            x.x.clone(),
            z.x.clone(),
            vec![
                reused("X (CARE residual of the DARE solution)", rx),
                reused("Z (CARE residual of the DARE solution)", rz),
            ],
        ));
    }
    let (gm_ct, xc, zc) = gamma_min(gc)?;
    if (gm_ct - gm).abs() > crate::tol::GAMMA_AGREE * gm {
        return Err(HinfError::Numerical(format!(
            "γ_min from the discrete Riccati equations ({gm}) and from the bilinear \
             continuous problem ({gm_ct}) disagree: the problem is too ill-conditioned"
        )));
    }
    let reports = vec![report("X (CARE)", &xc), report("Z (CARE)", &zc)];
    Ok((xc.x, zc.x, reports))
}

/// The central controller (positive feedback) of a continuous shaped plant at level γ from
/// the stabilizing solutions `x`, `z` of its Riccati equations.
fn central_ct(
    g: &StateSpace,
    gamma: f64,
    x: &DMatrix<f64>,
    z: &DMatrix<f64>,
) -> Result<StateSpace> {
    let (a, b, c, d) = (g.a(), g.b(), g.c(), g.d());
    let n = g.n();
    let nu = g.nu();
    let r = DMatrix::<f64>::identity(nu, nu) + d.transpose() * d;
    let f = -(r
        .clone()
        .lu()
        .solve(&(d.transpose() * c + b.transpose() * x))
        .ok_or_else(|| HinfError::Numerical("I + DᵀD singular".into()))?);
    let g2 = gamma * gamma;
    let l = DMatrix::<f64>::identity(n, n) * (1.0 - g2) + x * z;
    // L⁻ᵀ Z Cᵀ
    let lzc = l
        .transpose()
        .lu()
        .solve(&(z * c.transpose()))
        .ok_or_else(|| {
            HinfError::InvalidArgument(format!(
                "γ = {gamma} is too close to γ_min: (1 − γ²)I + XZ is singular; use a factor > 1"
            ))
        })?;
    let bk = &lzc * g2;
    let ak = a + b * &f + &bk * (c + d * &f);
    let ck = b.transpose() * x;
    let dk = -d.transpose();
    Ok(StateSpace::new(ak, bk, ck, dk, SampleTime::Continuous)?)
}

/// `[y; u]` from `[d_y; d_u]` for `y = G(u + d_u) + d_y`, `u = −K y`: the 4-block
/// `[I; −K](I + GK)⁻¹[I  G]`.
pub fn four_block(g: &StateSpace, k: &StateSpace) -> Result<StateSpace> {
    if !g.time().compatible(&k.time()) {
        return Err(HinfError::InvalidArgument(
            "plant and controller have different sample times".into(),
        ));
    }
    let (ny, nu) = (g.ny(), g.nu());
    let (ng, nk) = (g.n(), k.n());
    let e = (DMatrix::<f64>::identity(ny, ny) + g.d() * k.d())
        .try_inverse()
        .ok_or_else(|| {
            HinfError::InvalidArgument("I + D_G D_K is singular (ill-posed loop)".into())
        })?;
    // y = E (C_g x_g − D_g C_k x_k + d_y + D_g d_u)
    let yx = &e * g.c();
    let yk = -(&e * g.d() * k.c());
    let ydy = e.clone();
    let ydu = &e * g.d();
    // u = −C_k x_k − D_k y
    let ux = -(k.d() * &yx);
    let uk = -(k.c() + k.d() * &yk);
    let udy = -(k.d() * &ydy);
    let udu = -(k.d() * &ydu);
    let n = ng + nk;
    let mut a = DMatrix::<f64>::zeros(n, n);
    let mut b = DMatrix::<f64>::zeros(n, ny + nu);
    let mut c = DMatrix::<f64>::zeros(ny + nu, n);
    let mut d = DMatrix::<f64>::zeros(ny + nu, ny + nu);
    // x_g⁺ = A_g x_g + B_g (u + d_u)
    a.view_mut((0, 0), (ng, ng))
        .copy_from(&(g.a() + g.b() * &ux));
    a.view_mut((0, ng), (ng, nk)).copy_from(&(g.b() * &uk));
    b.view_mut((0, 0), (ng, ny)).copy_from(&(g.b() * &udy));
    b.view_mut((0, ny), (ng, nu))
        .copy_from(&(g.b() * (&udu + DMatrix::<f64>::identity(nu, nu))));
    // x_k⁺ = A_k x_k + B_k y
    a.view_mut((ng, 0), (nk, ng)).copy_from(&(k.b() * &yx));
    a.view_mut((ng, ng), (nk, nk))
        .copy_from(&(k.a() + k.b() * &yk));
    b.view_mut((ng, 0), (nk, ny)).copy_from(&(k.b() * &ydy));
    b.view_mut((ng, ny), (nk, nu)).copy_from(&(k.b() * &ydu));
    c.view_mut((0, 0), (ny, ng)).copy_from(&yx);
    c.view_mut((0, ng), (ny, nk)).copy_from(&yk);
    c.view_mut((ny, 0), (nu, ng)).copy_from(&ux);
    c.view_mut((ny, ng), (nu, nk)).copy_from(&uk);
    d.view_mut((0, 0), (ny, ny)).copy_from(&ydy);
    d.view_mut((0, ny), (ny, nu)).copy_from(&ydu);
    d.view_mut((ny, 0), (nu, ny)).copy_from(&udy);
    d.view_mut((ny, ny), (nu, nu)).copy_from(&udu);
    Ok(StateSpace::new(a, b, c, d, g.time())?)
}

/// `m` one-sample delays `z⁻¹ I_m` at period ts.
fn delay(m: usize, ts: f64) -> Result<StateSpace> {
    Ok(StateSpace::new(
        DMatrix::zeros(m, m),
        DMatrix::identity(m, m),
        DMatrix::identity(m, m),
        DMatrix::zeros(m, m),
        SampleTime::discrete(ts)?,
    )?)
}

fn pole_measure(sys: &StateSpace) -> Result<(f64, bool)> {
    let p = sys.poles()?;
    Ok(if sys.time().is_continuous() {
        let a = p.iter().map(|z| z.re).fold(f64::NEG_INFINITY, f64::max);
        (a, a < 0.0)
    } else {
        let r = p.iter().map(|z| z.norm()).fold(0.0, f64::max);
        (r, r < 1.0)
    })
}

/// McFarlane–Glover loopshaping of `plant` with weights `w1` (input, nu×nu) and `w2` (output,
/// ny×ny), identity when `None` (module documentation).
///
/// # Errors
/// Mixed sample times or wrong weight shapes, factor ≤ 1, the strictly proper option on a
/// continuous plant, Riccati failures (with their reason), a shaped plant with a pole at
/// z = −1.
pub fn loopshape(
    plant: &StateSpace,
    w1: Option<&StateSpace>,
    w2: Option<&StateSpace>,
    opt: &LoopshapeOptions,
) -> Result<Loopshape> {
    if !(opt.factor.is_finite() && opt.factor > 1.0) {
        return Err(HinfError::InvalidArgument(format!(
            "factor {} must be > 1 (γ = factor·γ_min; 1.1 is usual)",
            opt.factor
        )));
    }
    let time = plant.time();
    let w1 = match w1 {
        Some(w) => w.clone(),
        None => unit_gain(plant.nu(), time)?,
    };
    let w2 = match w2 {
        Some(w) => w.clone(),
        None => unit_gain(plant.ny(), time)?,
    };
    if w1.nu() != plant.nu()
        || w1.ny() != plant.nu()
        || w2.nu() != plant.ny()
        || w2.ny() != plant.ny()
    {
        return Err(HinfError::InvalidArgument(format!(
            "W1 must be {0}x{0} and W2 {1}x{1} for a {1}x{0} plant (got {2}x{3} and {4}x{5})",
            plant.nu(),
            plant.ny(),
            w1.ny(),
            w1.nu(),
            w2.ny(),
            w2.nu()
        )));
    }
    let gs = balance_states(&series(&series(&w1, plant)?, &w2)?)?;
    let mut riccati = Vec::new();
    let (gamma_min_v, gamma, ks) = match time {
        SampleTime::Continuous => {
            if opt.strictly_proper {
                return Err(HinfError::InvalidArgument(
                    "--strictly-proper applies to discrete-time plants (a continuous central \
                     controller is strictly proper when the shaped plant is)"
                        .into(),
                ));
            }
            let (gm, x, z) = gamma_min(&gs)?;
            riccati.push(report("X (CARE)", &x));
            riccati.push(report("Z (CARE)", &z));
            let gamma = opt.factor * gm;
            let kpos = central_ct(&gs, gamma, &x.x, &z.x)?;
            (gm, gamma, negate(&kpos)?)
        }
        SampleTime::Discrete { ts } => {
            let design = if opt.strictly_proper {
                series(&delay(gs.nu(), ts)?, &gs)?
            } else {
                gs.clone()
            };
            let (gm, x, z) = gamma_min(&design)?;
            riccati.push(report("X (DARE)", &x));
            riccati.push(report("Z (DARE)", &z));
            let gc = bilinear_to_continuous(&design)?;
            let (xc, zc, rep) = continuous_solutions(&gc, gm, &x, &z)?;
            riccati.extend(rep);
            let gamma = opt.factor * gm;
            let kpos_ct = central_ct(&gc, gamma, &xc, &zc)?;
            let kpos = bilinear_to_discrete(&kpos_ct, ts)?;
            let kneg = negate(&kpos)?;
            let ks = if opt.strictly_proper {
                series(&kneg, &delay(gs.nu(), ts)?)?
            } else {
                kneg
            };
            (gm, gamma, ks)
        }
    };
    let controller = series(&series(&w2, &ks)?, &w1)?;
    let cl = feedback(plant, &controller, -1.0)?;
    // the achieved norm and the closed loop's poles are independent: one on each core
    let (achieved, poles) = rayon::join(
        || -> Result<f64> { Ok(four_block(&gs, &ks)?.hinf_norm()?.value) },
        || pole_measure(&cl),
    );
    let (achieved, (closed_loop_radius, closed_loop_stable)) = (achieved?, poles?);
    Ok(Loopshape {
        gamma_min: gamma_min_v,
        gamma,
        achieved,
        shaped_plant: gs,
        shaped_controller: ks,
        controller,
        closed_loop_stable,
        closed_loop_radius,
        riccati,
    })
}

/// A diagonal (power-of-two) state scaling that balances `[A B; C 0]` (as MATLAB's `ssbal`):
/// the transfer function is unchanged, and the Riccati equations of the loopshaping problem do
/// not see the scale disparity of, e.g., a plant in metres driven in newtons.
fn balance_states(g: &StateSpace) -> Result<StateSpace> {
    let (n, nu, ny) = (g.n(), g.nu(), g.ny());
    let m = n + nu.max(ny);
    let mut big = DMatrix::<f64>::zeros(m, m);
    big.view_mut((0, 0), (n, n)).copy_from(g.a());
    big.view_mut((0, n), (n, nu)).copy_from(g.b());
    big.view_mut((n, 0), (ny, n)).copy_from(g.c());
    let (_, d) = sd_model::linalg::expm::balance_diag(&big);
    // keep only the state part of the scaling, relative to the input/output one
    let du = d.get(n).cloned().unwrap_or(1.0);
    let dx: Vec<f64> = d[..n].iter().map(|v| v / du).collect();
    let a = DMatrix::from_fn(n, n, |i, j| g.a()[(i, j)] * dx[j] / dx[i]);
    let b = DMatrix::from_fn(n, nu, |i, j| g.b()[(i, j)] / dx[i]);
    let c = DMatrix::from_fn(ny, n, |i, j| g.c()[(i, j)] * dx[j]);
    Ok(StateSpace::new(a, b, c, g.d().clone(), g.time())?)
}

fn negate(k: &StateSpace) -> Result<StateSpace> {
    Ok(StateSpace::new(
        k.a().clone(),
        k.b().clone(),
        -k.c(),
        -k.d(),
        k.time(),
    )?)
}
