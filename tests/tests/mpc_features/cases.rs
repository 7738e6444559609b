//! Random models and settings for each feature combination, and the
//! translation of [`MpcSettings`] into the reference's plain statement
//! ([`Plain`]), written here from the settings' documented meaning.

use super::reference::{Plain, PlainBounds, PlainTarget, PlainTerminal, riccati_by_iteration};
use kestrel_core::formats::SsModel;
use kestrel_mpc::{
    Blocking, Bounds, InputTarget, MpcSettings, Parameter, SoftPenalty, Terminal, TerminalSet,
    Weight,
};
use nalgebra::{DMatrix, DVector};
use rand::{RngExt, SeedableRng};
use rand_xoshiro::SplitMix64;

/// Reproducible random numbers (the workspace's seeded SplitMix64).
pub struct Rng(SplitMix64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(SplitMix64::seed_from_u64(seed))
    }
    /// Uniform in [-1, 1).
    pub fn sym(&mut self) -> f64 {
        self.0.random::<f64>() * 2.0 - 1.0
    }
    /// Uniform in [lo, hi).
    pub fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.0.random::<f64>()
    }
    /// Uniform integer in lo..=hi.
    pub fn int(&mut self, lo: usize, hi: usize) -> usize {
        lo + (self.0.random::<u64>() % (hi - lo + 1) as u64) as usize
    }
    /// True with probability `p`.
    pub fn chance(&mut self, p: f64) -> bool {
        self.0.random::<f64>() < p
    }
    pub fn mat(&mut self, r: usize, c: usize) -> DMatrix<f64> {
        DMatrix::from_fn(r, c, |_, _| self.sym())
    }
    pub fn psd(&mut self, n: usize, floor: f64) -> DMatrix<f64> {
        let l = self.mat(n, n);
        &l * l.transpose() + DMatrix::identity(n, n) * floor
    }
    /// A point of the box `[lb, ub]`.
    pub fn in_box(&mut self, lb: &DVector<f64>, ub: &DVector<f64>) -> DVector<f64> {
        DVector::from_fn(lb.len(), |i, _| self.uniform(lb[i], ub[i]))
    }
}

/// A random discrete model, spectral radius 0.95, no feed-through.
pub fn random_model(rng: &mut Rng, nx: usize, nu: usize, ny: usize) -> SsModel {
    let a0 = rng.mat(nx, nx);
    let rho = kestrel_core::eig::spectral_radius(&a0).unwrap();
    SsModel::new(
        0.05,
        a0 * (0.95 / rho.max(1e-3)),
        rng.mat(nx, nu),
        rng.mat(ny, nx),
        DMatrix::zeros(ny, nu),
    )
    .unwrap()
}

/// One feature of the settings.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Feature {
    /// No input bounds (every combination has them otherwise).
    NoInputBounds,
    DuWeight,
    DuBounds,
    OutputHard,
    OutputSoft,
    StateHard,
    StateSoft,
    Preview,
    TargetFixed,
    TargetParameter,
    /// Input bounds shifted by one or two extra parameters.
    ParamInputBounds,
    /// Input-move, output and state bounds shifted by the extra parameters
    /// too (with `ParamInputBounds`).
    ParamOtherBounds,
    /// Soft input bounds.
    InputSoft,
    /// Soft input-move bounds (with `DuBounds`).
    DuSoft,
    TerminalNone,
    TerminalLq,
    TerminalState,
    TerminalSet,
    /// Soft bounds with the default penalty (`SoftPenalty::default()`,
    /// an exact penalty) instead of a random small one.
    DefaultPenalty,
    /// Few parameters (for the explicit law): one extra parameter, a
    /// preview of two steps.
    SmallTheta,
}

/// A random weight in one of the three forms.
fn weight(rng: &mut Rng, n: usize, scale: f64) -> Weight {
    match rng.int(0, 2) {
        0 => Weight::Scalar(scale * rng.uniform(0.2, 1.5)),
        1 => Weight::Diagonal((0..n).map(|_| scale * rng.uniform(0.1, 1.5)).collect()),
        _ => Weight::Matrix(rng.psd(n, 0.1) * (0.5 * scale)),
    }
}

/// Random bounds on `k` entries within `[-hi, -lo] .. [lo, hi]` in size,
/// with now and then a missing side or a missing entry.
fn bounds(rng: &mut Rng, k: usize, lo: f64, hi: f64, gaps: bool) -> Bounds {
    let mut lower = DVector::from_fn(k, |_, _| -rng.uniform(lo, hi));
    let mut upper = DVector::from_fn(k, |_, _| rng.uniform(lo, hi));
    if gaps {
        for i in 0..k {
            match rng.int(0, 5) {
                0 => lower[i] = f64::NEG_INFINITY,
                1 => upper[i] = f64::INFINITY,
                2 if k > 1 && i == k - 1 => {
                    lower[i] = f64::NEG_INFINITY;
                    upper[i] = f64::INFINITY;
                }
                _ => {}
            }
        }
    }
    Bounds::new(lower, upper)
}

/// A random shift (`k x np`) of the finite entries of `b`, moving both
/// sides alike or each on its own.
fn shift(rng: &mut Rng, b: Bounds, np: usize, size: f64) -> Bounds {
    let k = b.len();
    let finite = |v: &DVector<f64>, s: DMatrix<f64>| {
        DMatrix::from_fn(k, np, |i, j| if v[i].is_finite() { s[(i, j)] } else { 0.0 })
    };
    if rng.chance(0.5) {
        let s = rng.mat(k, np) * size;
        let lower_shift = finite(&b.lower, s.clone());
        let upper_shift = finite(&b.upper, s);
        Bounds {
            lower_shift: Some(lower_shift),
            upper_shift: Some(upper_shift),
            ..b
        }
    } else {
        // Each side on its own: smaller, so hard bounds stay feasible
        // over the whole parameter box.
        let (l, u) = (rng.mat(k, np) * (0.6 * size), rng.mat(k, np) * (0.6 * size));
        Bounds {
            lower_shift: Some(finite(&b.lower, l)),
            upper_shift: Some(finite(&b.upper, u)),
            ..b
        }
    }
}

fn soft(rng: &mut Rng, default: bool) -> SoftPenalty {
    if default {
        return SoftPenalty::default();
    }
    SoftPenalty {
        quadratic: rng.uniform(1.0, 50.0),
        linear: if rng.chance(0.3) {
            0.0
        } else {
            rng.uniform(0.1, 20.0)
        },
    }
}

/// Random settings with these features for a model of these sizes.
pub fn settings(
    rng: &mut Rng,
    (nx, nu, ny): (usize, usize, usize),
    blocking: Option<&[usize]>,
    features: &[Feature],
) -> MpcSettings {
    let has = |f: Feature| features.contains(&f);
    let horizon = blocking.map_or_else(|| rng.int(2, 6), |b| b.iter().sum());
    let mut s = MpcSettings {
        horizon,
        blocking: blocking.map(|b| Blocking::new(b.to_vec()).unwrap()),
        q1: weight(rng, ny, 2.0),
        q2: weight(rng, nu, 0.1),
        terminal: if rng.chance(0.5) {
            Terminal::StageWeight
        } else {
            Terminal::Output(weight(rng, ny, 2.0))
        },
        state_bound: 2.0,
        reference_bound: 1.0,
        input_parameter_bound: 1.5,
        ..MpcSettings::default()
    };
    let np = if has(Feature::ParamInputBounds) {
        rng.int(1, if has(Feature::SmallTheta) { 1 } else { 2 })
    } else {
        0
    };
    s.parameters = (0..np)
        .map(|i| {
            Parameter::new(
                format!("p{i}"),
                -rng.uniform(0.2, 1.0),
                rng.uniform(0.2, 1.0),
            )
        })
        .collect();
    if !has(Feature::NoInputBounds) {
        let mut b = bounds(rng, nu, 0.4, 1.2, false);
        if np > 0 {
            b = shift(rng, b, np, 0.25);
        }
        if has(Feature::InputSoft) {
            b = b.with_soft(soft(rng, has(Feature::DefaultPenalty)));
        }
        s.input_bounds = Some(b);
    }
    if has(Feature::DuWeight) {
        s.du_weight = Some(weight(rng, nu, 0.5));
    }
    if has(Feature::DuBounds) {
        let mut b = bounds(rng, nu, 0.1, 0.5, true);
        if np > 0 && has(Feature::ParamOtherBounds) {
            // Small enough that a zero move stays inside over the box.
            b = shift(rng, b, np, 0.04);
        }
        if has(Feature::DuSoft) {
            b = b.with_soft(soft(rng, has(Feature::DefaultPenalty)));
        }
        s.du_bounds = Some(b);
    }
    for (hard, soft_f, state) in [
        (Feature::OutputHard, Feature::OutputSoft, false),
        (Feature::StateHard, Feature::StateSoft, true),
    ] {
        if !(has(hard) || has(soft_f)) {
            continue;
        }
        let k = if state { nx } else { ny };
        let (lo, hi) = match (has(hard), state) {
            (true, false) => (0.6, 1.8),
            (true, true) => (1.0, 2.2),
            (false, _) => (0.3, 1.5),
        };
        let mut b = bounds(rng, k, lo, hi, true);
        if np > 0 && has(Feature::ParamOtherBounds) {
            b = shift(rng, b, np, 0.3);
        }
        if has(soft_f) {
            b = b.with_soft(soft(rng, has(Feature::DefaultPenalty)));
        }
        if state {
            s.state_bounds = Some(b);
        } else {
            s.output_bounds = Some(b);
        }
    }
    if has(Feature::Preview) {
        s.preview = if has(Feature::SmallTheta) {
            2.min(horizon)
        } else {
            rng.int(2.min(horizon), horizon)
        };
    }
    if has(Feature::TargetFixed) {
        s.input_target = InputTarget::Fixed(DVector::from_fn(nu, |_, _| 0.3 * rng.sym()));
    }
    if has(Feature::TargetParameter) {
        s.input_target = InputTarget::Parameter;
    }
    if has(Feature::TerminalNone) {
        s.terminal = Terminal::None;
    }
    if has(Feature::TerminalLq) {
        s.terminal = Terminal::Lq;
    }
    if has(Feature::TerminalState) {
        s.terminal = Terminal::State(rng.psd(nx, 0.2));
    }
    if has(Feature::TerminalSet) {
        let k = rng.int(2, 4);
        s.terminal_set = Some(TerminalSet {
            a: rng.mat(k, nx),
            b: DVector::from_fn(k, |_, _| rng.uniform(0.4, 1.5)),
        });
    }
    s
}

/// A weight as a matrix, read from its documented meaning.
fn resolve(w: &Weight, n: usize) -> DMatrix<f64> {
    match w {
        Weight::Scalar(s) => DMatrix::identity(n, n) * *s,
        Weight::Diagonal(d) => DMatrix::from_diagonal(&DVector::from_column_slice(d)),
        Weight::Matrix(m) => m.clone(),
    }
}

fn plain_bounds(b: &Bounds, np: usize) -> PlainBounds {
    let k = b.lower.len();
    PlainBounds {
        lower: b.lower.clone(),
        upper: b.upper.clone(),
        lower_shift: b
            .lower_shift
            .clone()
            .unwrap_or_else(|| DMatrix::zeros(k, np)),
        upper_shift: b
            .upper_shift
            .clone()
            .unwrap_or_else(|| DMatrix::zeros(k, np)),
        soft: b.soft.map(|s| (s.quadratic, s.linear)),
    }
}

/// The reference's statement of `settings` on `model`.
pub fn plain(model: &SsModel, s: &MpcSettings) -> Plain {
    let (nu, ny) = (model.b.ncols(), model.c.nrows());
    let q1 = resolve(&s.q1, ny);
    let q2 = resolve(&s.q2, nu);
    let terminal = match &s.terminal {
        Terminal::StageWeight => PlainTerminal::Output(q1.clone()),
        Terminal::Output(w) => PlainTerminal::Output(resolve(w, ny)),
        Terminal::State(p) => PlainTerminal::State(p.clone()),
        Terminal::Lq => PlainTerminal::State(riccati_by_iteration(
            &model.a,
            &model.b,
            &(model.c.transpose() * &q1 * &model.c),
            &q2,
        )),
        Terminal::None => PlainTerminal::Zero,
    };
    let np = s.parameters.len();
    Plain {
        a: model.a.clone(),
        b: model.b.clone(),
        c: model.c.clone(),
        blocks: s
            .blocking
            .as_ref()
            .map_or_else(|| vec![1; s.horizon], |b| b.lengths().to_vec()),
        q1,
        q2,
        du_weight: s.du_weight.as_ref().map(|w| resolve(w, nu)),
        terminal,
        preview: s.preview,
        target: match &s.input_target {
            InputTarget::Zero => PlainTarget::Zero,
            InputTarget::Fixed(t) => PlainTarget::Fixed(t.clone()),
            InputTarget::Parameter => PlainTarget::Parameter,
        },
        input: s.input_bounds.as_ref().map(|b| plain_bounds(b, np)),
        du: s.du_bounds.as_ref().map(|b| plain_bounds(b, np)),
        output: s.output_bounds.as_ref().map(|b| plain_bounds(b, np)),
        state: s.state_bounds.as_ref().map(|b| plain_bounds(b, np)),
        terminal_set: s.terminal_set.as_ref().map(|t| (t.a.clone(), t.b.clone())),
        np,
        disturbance: None,
    }
}

/// The reference's statement of an offset-free design: the disturbance
/// maps `(Bd, Cd)` read off the augmented model `[A, Bd; 0, I]`,
/// `[C, Cd]` (whose other blocks must be the model's).
pub fn plain_offset_free(model: &SsModel, s: &MpcSettings, augmented: &SsModel) -> Plain {
    let (nx, ny) = (model.a.nrows(), model.c.nrows());
    let na = augmented.a.nrows();
    let nd = na - nx;
    assert_eq!(
        augmented.a.view((0, 0), (nx, nx)),
        model.a.view((0, 0), (nx, nx))
    );
    assert_eq!(
        augmented.a.view((nx, nx), (nd, nd)),
        DMatrix::identity(nd, nd)
    );
    assert_eq!(augmented.a.view((nx, 0), (nd, nx)).amax(), 0.0);
    assert_eq!(augmented.b.rows(0, nx), model.b.rows(0, nx));
    assert_eq!(augmented.b.rows(nx, nd).amax(), 0.0);
    assert_eq!(augmented.c.columns(0, nx), model.c.columns(0, nx));
    let bd = augmented.a.view((0, nx), (nx, nd)).into_owned();
    let cd = augmented.c.view((0, nx), (ny, nd)).into_owned();
    Plain {
        disturbance: Some((bd, cd)),
        ..plain(model, s)
    }
}
