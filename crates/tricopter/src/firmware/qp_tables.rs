//! The Rust source of `avr/firmware/src/generated_qp.rs`: the thesis-sized
//! MPC problem as the box QP the firmware's `qp` builds solve exactly with
//! kestrel-qp each period.

use crate::firmware::design::FirmwareDesign;
use crate::firmware::error::DesignError;
use std::fmt::Write as _;

/// The box QP of the design's problem (`d.qp`, kestrel-fgm's `BoxQp` of the
/// mpQP) in the firmware's layout, in f64: `min 1/2 z'Hz + q'z` subject to
/// `lo <= z <= hi`, with `q = F theta + f0`, `lo = LO theta + lo0`,
/// `hi = HI theta + hi0` and `theta = [x; p_ref, q_ref, r_ref; throttle]`.
/// Matrices are row-major: `f` is `n x p` (row `i` gives `q_i`), as are
/// `lo` and `hi`.
#[derive(Clone, Debug, PartialEq)]
pub struct QpTables {
    /// Decision variables `n`.
    pub n: usize,
    /// Parameters `p`.
    pub p: usize,
    /// Hessian, `n x n`, row-major.
    pub h: Vec<f64>,
    /// Its inverse, `n x n`, row-major (the fallback's unconstrained
    /// optimum `-H^-1 q`); zeros if `H` is singular.
    pub hinv: Vec<f64>,
    /// Linear term map, `n x p`, row-major.
    pub f: Vec<f64>,
    /// Constant linear term, `n`.
    pub f0: Vec<f64>,
    /// Lower bound map, `n x p`, row-major.
    pub lo: Vec<f64>,
    /// Lower bound offset, `n`.
    pub lo0: Vec<f64>,
    /// Upper bound map, `n x p`, row-major.
    pub hi: Vec<f64>,
    /// Upper bound offset, `n`.
    pub hi0: Vec<f64>,
    /// The parameter box's lower end, `p` (where the problem is posed).
    pub theta_lb: Vec<f64>,
    /// The parameter box's upper end, `p`.
    pub theta_ub: Vec<f64>,
}

impl QpTables {
    /// The box QP of the design `d` (its `qp`).
    pub fn of(d: &FirmwareDesign) -> Self {
        let qp = &d.qp;
        let (n, p) = (qp.n(), qp.p());
        let rows = |m: &nalgebra::DMatrix<f64>| -> Vec<f64> {
            (0..m.nrows())
                .flat_map(|i| (0..m.ncols()).map(move |j| (i, j)))
                .map(|(i, j)| m[(i, j)])
                .collect()
        };
        QpTables {
            n,
            p,
            h: rows(&qp.h),
            hinv: rows(
                &qp.h
                    .clone()
                    .try_inverse()
                    .unwrap_or_else(|| nalgebra::DMatrix::zeros(n, n)),
            ),
            // `f_theta` is p x n (q = f_theta' theta + f): F is its transpose.
            f: rows(&qp.f_theta.transpose()),
            f0: qp.f.iter().copied().collect(),
            lo: rows(&qp.lo_theta),
            lo0: qp.lo0.iter().copied().collect(),
            hi: rows(&qp.hi_theta),
            hi0: qp.hi0.iter().copied().collect(),
            theta_lb: qp.theta_lb.iter().copied().collect(),
            theta_ub: qp.theta_ub.iter().copied().collect(),
        }
    }

    /// The QP data at `theta` (`p` entries): `(q, lo, hi)`, each `n`.
    pub fn data_at(&self, theta: &[f64]) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let affine = |m: &[f64], c: &[f64]| -> Vec<f64> {
            m.chunks_exact(self.p)
                .zip(c)
                .map(|(row, c0)| {
                    row.iter()
                        .zip(theta)
                        .fold(*c0, |acc, (a, t)| if *a == 0.0 { acc } else { acc + a * t })
                })
                .collect()
        };
        (
            affine(&self.f, &self.f0),
            affine(&self.lo, &self.lo0),
            affine(&self.hi, &self.hi0),
        )
    }

    /// Every value of the tables, in the order of the fields (the `static`
    /// arrays of the generated file).
    pub fn values(&self) -> impl Iterator<Item = &f64> {
        self.h
            .iter()
            .chain(&self.hinv)
            .chain(&self.f)
            .chain(&self.f0)
            .chain(&self.lo)
            .chain(&self.lo0)
            .chain(&self.hi)
            .chain(&self.hi0)
            .chain(&self.theta_lb)
            .chain(&self.theta_ub)
    }

    /// Non-zero entries of the three parameter maps (the multiply-adds of
    /// one period's set-up; the firmware skips the zeros).
    pub fn setup_terms(&self) -> usize {
        self.f
            .iter()
            .chain(&self.lo)
            .chain(&self.hi)
            .filter(|v| **v != 0.0)
            .count()
    }
}

/// The Rust source of the `qp` builds' tables
/// (`avr/firmware/src/generated_qp.rs`): [`QpTables`] of the design in
/// f32, as `static` arrays (the firmware keeps them in RAM; [`QpTables::values`]
/// lists them, 170 for the thesis-sized problem).
///
/// # Errors
/// [`DesignError::Unsupported`] for a non-finite value or one beyond f32's
/// range.
pub fn generate_qp_tables(d: &FirmwareDesign) -> Result<String, DesignError> {
    let t = QpTables::of(d);
    let (n, p) = (t.n, t.p);
    if let Some(bad) = t
        .values()
        .find(|v| !v.is_finite() || v.abs() > f32::MAX as f64)
    {
        return Err(DesignError::Unsupported(format!(
            "QP table value {bad} is not a finite f32"
        )));
    }
    let mut s = String::new();
    let _ = writeln!(
        s,
        "// @generated by kestrel_tricopter::firmware::generate_qp_tables (`kestrel export --qp-out`, `kestrel codegen`); do not edit.\n\
         //\n\
         // The design's MPC problem ({n} variables, {p} parameters theta = [x; p_ref, q_ref, r_ref; throttle])\n\
         // as a box QP for kestrel-qp (firmware feature `qp`):\n\
         //   min 1/2 z'Hz + q'z  s.t.  lo <= z <= hi,\n\
         //   q = F theta + f0, lo = LO theta + lo0, hi = HI theta + hi0 (row-major, rows per variable).\n\
         // {} non-zero parameter terms per period.\n",
        t.setup_terms()
    );
    let _ = writeln!(
        s,
        "/// QP decision variables.\npub const QP_N: usize = {n};\n/// QP parameters.\npub const QP_P: usize = {p};"
    );
    let num = |v: &f64| format!("{:e}", *v as f32);
    let vector = |s: &mut String, name: &str, doc: &str, v: &[f64]| {
        let items: Vec<String> = v.iter().map(num).collect();
        let _ = writeln!(
            s,
            "/// {doc}\npub static {name}: [f32; QP_N] = [{}];",
            items.join(", ")
        );
    };
    let matrix = |s: &mut String, name: &str, doc: &str, m: &[f64], cols: &str, w: usize| {
        let _ = writeln!(
            s,
            "/// {doc}\n#[rustfmt::skip]\npub static {name}: [[f32; {cols}]; QP_N] = ["
        );
        for row in m.chunks_exact(w) {
            let items: Vec<String> = row.iter().map(num).collect();
            let _ = writeln!(s, "    [{}],", items.join(", "));
        }
        let _ = writeln!(s, "];");
    };
    matrix(
        &mut s,
        "QP_H",
        "The Hessian `H` (symmetric positive definite).",
        &t.h,
        "QP_N",
        n,
    );
    matrix(
        &mut s,
        "QP_HINV",
        "`H^-1` (the fallback's unconstrained optimum `-H^-1 q`).",
        &t.hinv,
        "QP_N",
        n,
    );
    matrix(
        &mut s,
        "QP_F",
        "The linear term's parameter map `F`.",
        &t.f,
        "QP_P",
        p,
    );
    vector(&mut s, "QP_F0", "The linear term's constant `f0`.", &t.f0);
    matrix(
        &mut s,
        "QP_LO",
        "The lower bounds' parameter map `LO`.",
        &t.lo,
        "QP_P",
        p,
    );
    vector(
        &mut s,
        "QP_LO0",
        "The lower bounds' constant `lo0`.",
        &t.lo0,
    );
    matrix(
        &mut s,
        "QP_HI",
        "The upper bounds' parameter map `HI`.",
        &t.hi,
        "QP_P",
        p,
    );
    vector(
        &mut s,
        "QP_HI0",
        "The upper bounds' constant `hi0`.",
        &t.hi0,
    );
    for (name, doc, v) in [
        ("QP_THETA_LB", "The parameter box's lower end.", &t.theta_lb),
        ("QP_THETA_UB", "The parameter box's upper end.", &t.theta_ub),
    ] {
        let items: Vec<String> = v.iter().map(num).collect();
        let _ = writeln!(
            s,
            "/// {doc}\npub static {name}: [f32; QP_P] = [{}];",
            items.join(", ")
        );
    }
    Ok(s)
}
