//! Disturbance-augmented models and their stationary Kalman filter
//! (feature `std`).
//!
//! A discrete plant `x+ = A x + B u`, `y = C x + D u` is augmented with
//! `nd` integrating disturbance states `d`:
//!
//! ```text
//! [x; d]+ = [A  Bd; 0  I] [x; d] + [B; 0] u + [Gx  0; 0  I] [wx; wd]
//! y       = [C  Cd]       [x; d] + D u + v
//! Cov(wx) = Qx,  Cov(wd) = Qd,  Cov(v) = R
//! ```
//!
//! [`Disturbance`] chooses the maps `Bd` (into the states) and `Cd` (into
//! the outputs): a constant input disturbance, an output offset, a
//! disturbance along the measured directions, or a random walk added to
//! the measured outputs every sample (an "acceleration" state when the
//! outputs are rates), or any maps. [`AugmentedModel`] builds the
//! augmented model and checks that the disturbance can be estimated
//! (`rank [A - I, Bd; C, Cd] = nx + nd`, Maeder, Borrelli and Morari 2009,
//! Prop. 1); [`AugmentedModel::design`] designs the stationary filter of
//! the augmented model with [`KalmanDesign`] from a [`DisturbanceNoise`]
//! (one covariance block for the plant's process noise, one for the
//! disturbances' random walk). The result, [`DisturbanceDesign`], holds
//! both.
//!
//! ```
//! use kestrel_core::formats::SsModel;
//! use kestrel_kalman::{AugmentedModel, Disturbance, DisturbanceNoise};
//! use nalgebra::{DMatrix, dmatrix};
//! // A first-order plant whose input is off by an unknown constant.
//! let plant = SsModel::new(0.1, dmatrix![0.9], dmatrix![0.1], dmatrix![1.0], dmatrix![0.0])?;
//! let aug = AugmentedModel::new(&plant, &Disturbance::Input)?;
//! assert_eq!((aug.nx, aug.nd, aug.model.nx()), (1, 1, 2));
//! // Process noise through B and C' (std 0.1 and 0.01 per sample), a
//! // random walk of 0.005 per sample on the disturbance, R = 1e-4.
//! let noise = DisturbanceNoise::inputs_and_outputs(&aug, 0.1, 0.01, 0.005, dmatrix![1e-4]);
//! let design = aug.design(&noise)?;
//! let m = &design.kalman.filter.m; // measurement-update gain, (nx + nd) x ny
//! assert_eq!(m.shape(), (2, 1));
//! assert!(m[(1, 0)] > 0.0); // the output error moves the disturbance estimate
//! // The run-time filter on the augmented state [x; d]:
//! let filter = design.kalman.filter::<f32, 2, 1, 1>()?;
//! # let _ = filter;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use crate::dare::check_shape;
use crate::{DareSettings, KalmanDesign, KalmanError, NoiseModel};
use kestrel_core::formats::SsModel;
use nalgebra::{DMatrix, DVector};

/// Relative singular-value threshold of the detectability rank test
/// `rank [A - I, Bd; C, Cd]` (relative to `max(sigma_max, 1)`).
pub const DETECTABILITY_RANK_TOLERANCE: f64 = 1e-9;

/// Singular values below this (relative to the largest) are dropped in
/// the pseudo-inverse of `C` for [`Disturbance::OutputIncrement`].
pub const PSEUDO_INVERSE_TOLERANCE: f64 = 1e-12;

/// How the `nd` integrating disturbance states enter the plant: the maps
/// `Bd` (`nx x nd`, into the state update) and `Cd` (`ny x nd`, into the
/// outputs).
#[derive(Clone, Debug, PartialEq)]
pub enum Disturbance {
    /// No disturbance states (`nd = 0`): the plain filter of the plant
    /// with the process-noise blocks of [`DisturbanceNoise`].
    None,
    /// A constant added to the inputs, `u + d`: `Bd = B`, `Cd = D`, `nd = nu`.
    Input,
    /// A constant added to the outputs: `Bd = 0`, `Cd = I`, `nd = ny`. Not
    /// detectable when `A` has an eigenvalue at 1 (an integrator), since
    /// the offset cannot then be told from the state.
    Output,
    /// A constant entering the states along the measured directions:
    /// `Bd = C'`, `Cd = 0`, `nd = ny`.
    OutputStates,
    /// A random walk added to the measured outputs every sample:
    /// `Bd = C^+` (the Moore–Penrose pseudo-inverse, so `C Bd = I` for a
    /// `C` of full row rank), `Cd = 0`, `nd = ny`. When the outputs are
    /// rates, `d` is an unmodelled acceleration (a gust, a model error).
    /// Equal to [`Disturbance::OutputStates`] when `C` has orthonormal rows
    /// (a selection of states).
    OutputIncrement,
    /// Any maps; `bd.ncols() == cd.ncols() == nd`.
    Custom {
        /// State map `Bd`, `nx x nd`.
        bd: DMatrix<f64>,
        /// Output map `Cd`, `ny x nd`.
        cd: DMatrix<f64>,
    },
}

impl Disturbance {
    /// The maps `(Bd, Cd)` of this disturbance for `plant`.
    ///
    /// # Errors
    /// [`KalmanError::DimensionMismatch`] or [`KalmanError::NonFinite`] for
    /// [`Disturbance::Custom`] maps that do not fit the plant or hold NaN.
    pub fn maps(&self, plant: &SsModel) -> Result<(DMatrix<f64>, DMatrix<f64>), KalmanError> {
        let (nx, ny) = (plant.a.nrows(), plant.c.nrows());
        Ok(match self {
            Disturbance::None => (DMatrix::zeros(nx, 0), DMatrix::zeros(ny, 0)),
            Disturbance::Input => (plant.b.clone(), plant.d.clone()),
            Disturbance::Output => (DMatrix::zeros(nx, ny), DMatrix::identity(ny, ny)),
            Disturbance::OutputStates => (plant.c.transpose(), DMatrix::zeros(ny, ny)),
            Disturbance::OutputIncrement => {
                let bd = if nx == 0 || ny == 0 {
                    DMatrix::zeros(nx, ny) // (nalgebra's SVD refuses an empty matrix)
                } else {
                    plant
                        .c
                        .clone()
                        .pseudo_inverse(PSEUDO_INVERSE_TOLERANCE)
                        .map_err(|reason| KalmanError::InvalidArgument {
                            name: "C",
                            reason: format!("pseudo-inverse: {reason}"),
                        })?
                };
                (bd, DMatrix::zeros(ny, ny))
            }
            Disturbance::Custom { bd, cd } => {
                let nd = bd.ncols();
                check_shape("Bd", bd, nx, nd)?;
                check_shape("Cd", cd, ny, nd)?;
                (bd.clone(), cd.clone())
            }
        })
    }
}

/// Whether the last `nd` states of the model `x+ = A x + B u` are
/// integrating disturbances: the last `nd` rows of `A` are `[0, I]` and
/// those of `B` zero (exactly). `false` when `nd` exceeds the states or the
/// matrices' rows differ.
///
/// ```
/// use nalgebra::dmatrix;
/// let a = dmatrix![0.9, 0.1; 0.0, 1.0];
/// let b = dmatrix![1.0; 0.0];
/// assert!(kestrel_kalman::augment::integrating_disturbances(&a, &b, 1));
/// assert!(!kestrel_kalman::augment::integrating_disturbances(&a, &b, 2));
/// ```
pub fn integrating_disturbances(a: &DMatrix<f64>, b: &DMatrix<f64>, nd: usize) -> bool {
    let na = a.nrows();
    nd <= na
        && a.ncols() == na
        && b.nrows() == na
        && (na - nd..na).all(|i| {
            (0..na).all(|j| a[(i, j)] == if i == j { 1.0 } else { 0.0 })
                && b.row(i).iter().all(|v| *v == 0.0)
        })
}

/// A plant model augmented with integrating disturbance states: the
/// augmented model's state is `[x; d]` (plant states first).
#[derive(Clone, Debug, PartialEq)]
pub struct AugmentedModel {
    /// The augmented model `[A, Bd; 0, I]`, `[B; 0]`, `[C, Cd]`, `D`, with
    /// the plant's sample time, operating point (`u0`, `y0`) and names;
    /// `x0` (if any) extended by zeros; no innovation gain `K`.
    pub model: SsModel,
    /// Number of plant states.
    pub nx: usize,
    /// Number of disturbance states.
    pub nd: usize,
    /// The state map `Bd`, `nx x nd`.
    pub bd: DMatrix<f64>,
    /// The output map `Cd`, `ny x nd`.
    pub cd: DMatrix<f64>,
}

impl AugmentedModel {
    /// Augments a discrete plant (`ts > 0`) with the disturbance states of
    /// `disturbance`.
    ///
    /// # Errors
    /// [`KalmanError::InvalidArgument`] for a continuous-time plant,
    /// [`KalmanError::DimensionMismatch`] / [`KalmanError::NonFinite`] for
    /// inconsistent or non-finite matrices, and
    /// [`KalmanError::DisturbanceNotDetectable`] when `nd > 0` and
    /// `rank [A - I, Bd; C, Cd] < nx + nd` (the augmented pair is then not
    /// detectable, whatever the noise).
    pub fn new(plant: &SsModel, disturbance: &Disturbance) -> Result<Self, KalmanError> {
        check_plant(plant)?;
        let (bd, cd) = disturbance.maps(plant)?;
        check_detectable(&plant.a, &plant.c, &bd, &cd)?;
        let (nx, nu, ny, nd) = (
            plant.a.nrows(),
            plant.b.ncols(),
            plant.c.nrows(),
            bd.ncols(),
        );
        let na = nx + nd;
        let mut a = DMatrix::identity(na, na);
        a.view_mut((0, 0), (nx, nx)).copy_from(&plant.a);
        a.view_mut((0, nx), (nx, nd)).copy_from(&bd);
        let mut b = DMatrix::zeros(na, nu);
        b.view_mut((0, 0), (nx, nu)).copy_from(&plant.b);
        let mut c = DMatrix::zeros(ny, na);
        c.view_mut((0, 0), (ny, nx)).copy_from(&plant.c);
        c.view_mut((0, nx), (ny, nd)).copy_from(&cd);
        let model = SsModel {
            ts: plant.ts,
            a,
            b,
            c,
            d: plant.d.clone(),
            k: None,
            x0: plant
                .x0
                .as_ref()
                .map(|x0| DVector::from_fn(na, |i, _| if i < nx { x0[i] } else { 0.0 })),
            u0: plant.u0.clone(),
            y0: plant.y0.clone(),
            inputs: plant.inputs.clone(),
            outputs: plant.outputs.clone(),
        };
        Ok(AugmentedModel {
            model,
            nx,
            nd,
            bd,
            cd,
        })
    }

    /// Reads an already augmented model whose last `nd` states are
    /// integrating disturbances (for instance an offset-free MPC's
    /// prediction model): the last `nd` rows of `A` must be `[0, I]` and
    /// those of `B` zero; `Bd` and `Cd` are read from the last `nd`
    /// columns of `A` and `C`. The model is kept as it is.
    ///
    /// # Errors
    /// As [`AugmentedModel::new`], and [`KalmanError::InvalidArgument`]
    /// when `nd` exceeds the number of states or the last `nd` states are
    /// not integrating disturbances.
    pub fn from_augmented(model: &SsModel, nd: usize) -> Result<Self, KalmanError> {
        check_plant(model)?;
        let na = model.a.nrows();
        if nd > na {
            return Err(KalmanError::InvalidArgument {
                name: "nd",
                reason: format!("{nd} disturbance states in a model of {na} states"),
            });
        }
        let nx = na - nd;
        if !integrating_disturbances(&model.a, &model.b, nd) {
            return Err(KalmanError::InvalidArgument {
                name: "model",
                reason: format!(
                    "the last {nd} states are not integrating disturbances (rows [0, I] of A, zero rows of B)"
                ),
            });
        }
        let bd = model.a.view((0, nx), (nx, nd)).into_owned();
        let cd = model.c.columns(nx, nd).into_owned();
        let a = model.a.view((0, 0), (nx, nx)).into_owned();
        let c = model.c.columns(0, nx).into_owned();
        check_detectable(&a, &c, &bd, &cd)?;
        Ok(AugmentedModel {
            model: model.clone(),
            nx,
            nd,
            bd,
            cd,
        })
    }

    /// The [`NoiseModel`] of the augmented model: `G = [Gx, 0; 0, I]`
    /// (`Gx` padded with zero rows when it has `nx` rows),
    /// `Q = [Qx, 0; 0, Qd]`, `R` and the bias of `noise`.
    ///
    /// # Errors
    /// [`KalmanError::DimensionMismatch`] or [`KalmanError::NonFinite`]
    /// when a block does not fit the model or holds NaN.
    pub fn noise_model(&self, noise: &DisturbanceNoise) -> Result<NoiseModel, KalmanError> {
        let (nx, nd) = (self.nx, self.nd);
        let na = nx + nd;
        let ny = self.model.c.nrows();
        let gx = &noise.plant_g;
        let nw = gx.ncols();
        let rows = if gx.nrows() == na { na } else { nx };
        check_shape("plant_g", gx, rows, nw)?;
        check_shape("plant_q", &noise.plant_q, nw, nw)?;
        check_shape("disturbance_q", &noise.disturbance_q, nd, nd)?;
        check_shape("R", &noise.r, ny, ny)?;
        if let Some(bias) = &noise.bias {
            let bm = DMatrix::from_column_slice(bias.len(), 1, bias.as_slice());
            check_shape("bias", &bm, ny, 1)?;
        }
        let mut g = DMatrix::zeros(na, nw + nd);
        g.view_mut((0, 0), (rows, nw)).copy_from(gx);
        g.view_mut((nx, nw), (nd, nd))
            .copy_from(&DMatrix::identity(nd, nd));
        let mut q = DMatrix::zeros(nw + nd, nw + nd);
        q.view_mut((0, 0), (nw, nw)).copy_from(&noise.plant_q);
        q.view_mut((nw, nw), (nd, nd))
            .copy_from(&noise.disturbance_q);
        Ok(NoiseModel {
            g: Some(g),
            q,
            r: noise.r.clone(),
            cross: None,
            bias: noise.bias.clone(),
        })
    }

    /// The stationary Kalman filter of the augmented model (default
    /// [`DareSettings`]).
    ///
    /// # Errors
    /// As [`AugmentedModel::noise_model`] and [`KalmanDesign::new`] (for
    /// instance [`KalmanError::NotDetectable`] or
    /// [`KalmanError::NotPositiveSemidefinite`]).
    pub fn design(&self, noise: &DisturbanceNoise) -> Result<DisturbanceDesign, KalmanError> {
        self.design_with(noise, &DareSettings::default())
    }

    /// [`AugmentedModel::design`] with explicit Riccati settings.
    ///
    /// # Errors
    /// As [`AugmentedModel::design`].
    pub fn design_with(
        &self,
        noise: &DisturbanceNoise,
        settings: &DareSettings,
    ) -> Result<DisturbanceDesign, KalmanError> {
        let noise = self.noise_model(noise)?;
        let kalman = KalmanDesign::with_settings(&self.model, &noise, settings)?;
        Ok(DisturbanceDesign {
            augmented: self.clone(),
            kalman,
        })
    }

    /// Splits an augmented state `[x; d]` into the plant state and the
    /// disturbance, or `None` when `z` does not have `nx + nd` entries.
    pub fn split<'a>(&self, z: &'a [f64]) -> Option<(&'a [f64], &'a [f64])> {
        (z.len() == self.nx + self.nd).then(|| z.split_at(self.nx))
    }
}

/// The process and measurement noise of a disturbance-augmented filter.
///
/// Process noise `G [wx; wd]` with `G = [Gx, 0; 0, I]`,
/// `Cov([wx; wd]) = [Qx, 0; 0, Qd]`: the plant's process noise `wx`
/// enters through `Gx`, each disturbance follows a random walk
/// `d+ = d + wd`.
#[derive(Clone, Debug, PartialEq)]
pub struct DisturbanceNoise {
    /// `Gx`, `nx x nw`: how the plant's process noise enters the plant
    /// states (zero on the disturbance states). Given with `nx + nd` rows
    /// it is used as it is, for noise that also enters the disturbance
    /// states.
    pub plant_g: DMatrix<f64>,
    /// `Qx = Cov(wx)`, `nw x nw`, symmetric positive semidefinite.
    pub plant_q: DMatrix<f64>,
    /// `Qd = Cov(wd)`, `nd x nd`: the disturbances' random walk per sample.
    pub disturbance_q: DMatrix<f64>,
    /// Measurement noise covariance `R`, `ny x ny`, positive definite.
    pub r: DMatrix<f64>,
    /// Known constant sensor bias, `ny` (removed by the filter as in
    /// [`NoiseModel::bias`]).
    pub bias: Option<DVector<f64>>,
}

impl DisturbanceNoise {
    /// Process noise through the inputs and along the measured directions,
    /// `Gx = [B, C']` (plant rows), `Qx = diag(input_std^2 I_nu,
    /// output_std^2 I_ny)`, a random walk of `disturbance_std` per sample
    /// on every disturbance state (`Qd = disturbance_std^2 I_nd`), the
    /// given `R` and no bias. The standard deviations are per sample.
    pub fn inputs_and_outputs(
        augmented: &AugmentedModel,
        input_std: f64,
        output_std: f64,
        disturbance_std: f64,
        r: DMatrix<f64>,
    ) -> Self {
        let nx = augmented.nx;
        let b = augmented.model.b.rows(0, nx);
        let c = augmented.model.c.columns(0, nx);
        let (nu, ny, nd) = (b.ncols(), c.nrows(), augmented.nd);
        let mut plant_g = DMatrix::zeros(nx, nu + ny);
        plant_g.view_mut((0, 0), (nx, nu)).copy_from(&b);
        plant_g
            .view_mut((0, nu), (nx, ny))
            .copy_from(&c.transpose());
        let plant_q = DMatrix::from_diagonal(&DVector::from_fn(nu + ny, |i, _| {
            if i < nu {
                input_std * input_std
            } else {
                output_std * output_std
            }
        }));
        DisturbanceNoise {
            plant_g,
            plant_q,
            disturbance_q: DMatrix::identity(nd, nd) * (disturbance_std * disturbance_std),
            r,
            bias: None,
        }
    }
}

/// A stationary Kalman filter on a disturbance-augmented model, from
/// [`AugmentedModel::design`].
#[derive(Clone, Debug, PartialEq)]
pub struct DisturbanceDesign {
    /// The augmented model and its disturbance maps.
    pub augmented: AugmentedModel,
    /// The filter design on the augmented model (its gains `M`, `L`, `P`
    /// in `kalman.filter`, run-time tables by [`KalmanDesign::gains`]).
    pub kalman: KalmanDesign,
}

impl DisturbanceDesign {
    /// Number of disturbance states (the last `nd` of the filter's state).
    pub fn nd(&self) -> usize {
        self.augmented.nd
    }

    /// The stationary measurement-update gain `M`, `(nx + nd) x ny`.
    pub fn gain(&self) -> &DMatrix<f64> {
        &self.kalman.filter.m
    }
}

/// A discrete plant with consistent, finite matrices.
fn check_plant(plant: &SsModel) -> Result<(), KalmanError> {
    if !(plant.ts.is_finite() && plant.ts > 0.0) {
        return Err(KalmanError::InvalidArgument {
            name: "ts",
            reason: format!(
                "the model must be discrete (ts > 0), found ts = {}",
                plant.ts
            ),
        });
    }
    let (nx, nu, ny) = (plant.a.nrows(), plant.b.ncols(), plant.c.nrows());
    check_shape("A", &plant.a, nx, nx)?;
    check_shape("B", &plant.b, nx, nu)?;
    check_shape("C", &plant.c, ny, nx)?;
    check_shape("D", &plant.d, ny, nu)
}

/// `rank [A - I, Bd; C, Cd] = nx + nd` (only when `nd > 0`: without
/// disturbance states the filter design's own detectability test applies).
fn check_detectable(
    a: &DMatrix<f64>,
    c: &DMatrix<f64>,
    bd: &DMatrix<f64>,
    cd: &DMatrix<f64>,
) -> Result<(), KalmanError> {
    let (nx, ny, nd) = (a.nrows(), c.nrows(), bd.ncols());
    if nd == 0 {
        return Ok(());
    }
    let mut pbh = DMatrix::zeros(nx + ny, nx + nd);
    pbh.view_mut((0, 0), (nx, nx))
        .copy_from(&(a - DMatrix::identity(nx, nx)));
    pbh.view_mut((0, nx), (nx, nd)).copy_from(bd);
    pbh.view_mut((nx, 0), (ny, nx)).copy_from(c);
    pbh.view_mut((nx, nx), (ny, nd)).copy_from(cd);
    let rank = if nx + ny == 0 {
        0 // (nalgebra's SVD refuses an empty matrix)
    } else {
        let sv = pbh.singular_values();
        let tol = DETECTABILITY_RANK_TOLERANCE * sv.max().max(1.0);
        sv.iter().filter(|s| **s > tol).count()
    };
    if rank < nx + nd {
        return Err(KalmanError::DisturbanceNotDetectable {
            rank,
            required: nx + nd,
        });
    }
    Ok(())
}
