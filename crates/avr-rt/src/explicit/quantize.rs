//! Design time (`std`): kestrel-empc's explicit controller as the 16-bit
//! table of [`Tree16`], and its check against the f64 evaluation.
//!
//! Scaling (all powers of two, so the hyperplane tests `a(theta) <= b(theta)`
//! need no shift at run time):
//! - parameter `j` gets `e_j` fraction bits, the most that keep its box
//!   within `i16` (`theta_j = q_j / 2^e_j`; from Q15.16 a rounding shift by
//!   `16 - e_j`);
//! - every row gets the same output scale `2^K`: gains
//!   `c_j = round(g_j 2^(K - e_j))`, constant `round(c 2^K)`, with `K` the
//!   largest for which every gain fits `i16` and `sum_j |c_j| max|q_j| +
//!   |c_0| < 2^31` for every row, so the kernel's 32-bit sum cannot
//!   overflow anywhere on the box (proved here, not sampled).
//!
//! [`Tree16Tables::row_error_bound`] bounds each row's value error (us for
//! the tricopter) from the rounding of gains, constant and parameter;
//! [`check_tree16`] measures the evaluation against kestrel-empc's f64 one.

use super::tree16::{Empc16Law, LEAF, NONE, NONE16, Tree16, Tree16Layout};
use kestrel_empc::{NO_ROW, OwnedTables};
use std::fmt::Write as _;

/// The 16-bit table of an explicit controller.
#[derive(Clone, Debug, PartialEq)]
pub struct Tree16Tables {
    /// Counts and scale.
    pub layout: Tree16Layout,
    /// The table's bytes ([`Tree16`]'s layout).
    pub bytes: Vec<u8>,
    /// Fraction bits `e_j` of every parameter.
    pub param_bits: Vec<i32>,
    /// Per row: a bound on `|quantised value - exact value|` on the box,
    /// in the output's units, from the rounding of the gains, the constant
    /// and the parameter (the Q15.16 input included).
    pub row_error_bound: Vec<f64>,
    /// Largest row value error bound over the law and bound rows.
    pub output_error_bound: f64,
    /// Tree depth (most nodes on a root-to-leaf path).
    pub depth: usize,
}

/// Why an explicit controller has no 16-bit table (the firmware design
/// maps it into its own error).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum QuantizeError {
    /// A table's size is not what it must be.
    Dimension {
        /// What was checked.
        what: &'static str,
        /// What the 16-bit table needs.
        expected: String,
        /// What was given.
        found: String,
    },
    /// The controller holds something the 16-bit table cannot (see
    /// [`quantize_tree`]), or an argument is out of range.
    Unsupported(String),
}

impl core::fmt::Display for QuantizeError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            QuantizeError::Dimension {
                what,
                expected,
                found,
            } => write!(f, "{what}: expected {expected}, found {found}"),
            QuantizeError::Unsupported(what) => write!(f, "unsupported design: {what}"),
        }
    }
}

impl std::error::Error for QuantizeError {}

fn unsupported(what: impl Into<String>) -> QuantizeError {
    QuantizeError::Unsupported(what.into())
}

/// Largest move of a tree hyperplane by rounding, as a fraction of the
/// parameter box, before it gets a row of its own (see [`quantize_tree`]).
pub const MAX_SHIFT: f64 = 1e-3;

/// Row encoding with the parameters' scaling.
struct Enc<'a> {
    p: usize,
    param_bits: &'a [i32],
    /// Largest |q_j| on the box (parameter units).
    qmax: &'a [f64],
    /// Largest |theta_j| on the box.
    mag: &'a [f64],
}

impl Enc<'_> {
    /// Gains `round(g_j 2^(K - e_j))` and constant `round(c 2^K)`.
    fn quant(&self, g: &[f64], kk: i32) -> (Vec<i64>, i64) {
        let c = (0..self.p)
            .map(|j| (g[j] * 2f64.powi(kk - self.param_bits[j])).round() as i64)
            .collect();
        (c, (g[self.p] * 2f64.powi(kk)).round() as i64)
    }
    /// Gains within `i16` and the sum within `i32` on the whole box.
    fn fits(&self, g: &[f64], kk: i32) -> bool {
        let (c, c0) = self.quant(g, kk);
        let sum: f64 = c
            .iter()
            .zip(self.qmax)
            .map(|(ci, q)| ci.unsigned_abs() as f64 * q)
            .sum::<f64>()
            + c0.unsigned_abs() as f64;
        c.iter().all(|ci| ci.unsigned_abs() <= 32767) && sum <= (i32::MAX - 1) as f64
    }
    /// Bound on |quantised value - exact value| on the box (row units).
    fn bound(&self, g: &[f64], kk: i32) -> f64 {
        let (c, c0) = self.quant(g, kk);
        let k2 = 2f64.powi(kk);
        let mut err = (c0 as f64 / k2 - g[self.p]).abs();
        for j in 0..self.p {
            let unit = 2f64.powi(-self.param_bits[j]);
            // The gain per parameter unit the kernel applies.
            let gain = c[j] as f64 / unit / k2;
            // Gain rounding over the box, and the parameter's rounding
            // (half a unit, plus half a Q15.16 step before the shift).
            err += (gain - g[j]).abs() * self.mag[j];
            err += gain.abs() * (0.5 * unit + 0.5 / 65536.0);
        }
        err
    }
    /// Norm of the gains over the box (row units per box half-width).
    fn gradient(&self, g: &[f64]) -> f64 {
        (0..self.p)
            .map(|j| (g[j] * self.mag[j]).powi(2))
            .sum::<f64>()
            .sqrt()
            .max(f64::MIN_POSITIVE)
    }
}

/// Quantises an explicit controller's tables (kestrel-empc's shared-tree
/// layout, [`kestrel_empc::build_controller`]) for [`Tree16`].
///
/// # Errors
/// [`QuantizeError::Unsupported`] for an explored set other than the box
/// (hull rows), more than 254 rows or laws, 32767 nodes, a non-finite or
/// inconsistent table, an unbounded parameter, or rows too large for a
/// scale of at least `2^0`.
///
/// Hyperplanes get rows of their own (see [`quantize_tree_with`]) up to 32,
/// as many as keep the table under [`TABLE_BUDGET`] bytes (all 32 if even
/// none does).
pub fn quantize_tree(t: &OwnedTables<f64>) -> Result<Tree16Tables, QuantizeError> {
    let most = quantize_tree_with(t, MAX_OWN_ROWS)?;
    if most.bytes.len() < TABLE_BUDGET {
        return Ok(most);
    }
    // Without any own row the table is smallest: if that does not fit
    // either (large trees), keep the most accurate one.
    if quantize_tree_with(t, 0)?.bytes.len() >= TABLE_BUDGET {
        return Ok(most);
    }
    for m in (0..MAX_OWN_ROWS).rev() {
        let q = quantize_tree_with(t, m)?;
        if q.bytes.len() < TABLE_BUDGET {
            return Ok(q);
        }
    }
    Ok(most)
}

/// The table size [`quantize_tree`] keeps under if it can (the issue's
/// 8 kB target, in decimal kilobytes).
pub const TABLE_BUDGET: usize = 8000;

/// Most hyperplane rows of their own [`quantize_tree`] gives.
pub const MAX_OWN_ROWS: usize = 32;

/// [`quantize_tree`] with at most `max_own_rows` hyperplanes given rows of
/// their own (the worst conditioned first; 23 bytes each for 9 parameters).
/// The layout is the narrow one unless the tree has more than 254 rows or
/// laws (then wide, [`Tree16Layout::wide`]).
pub fn quantize_tree_with(
    t: &OwnedTables<f64>,
    max_own_rows: usize,
) -> Result<Tree16Tables, QuantizeError> {
    let k = t.n_outputs.max(1);
    let w = t.n_params + 1;
    let wide =
        t.rows.len() / w + max_own_rows >= NONE as usize || t.laws.len() / k >= NONE as usize;
    quantize_tree_layout(t, max_own_rows, wide)
}

/// [`quantize_tree_with`] in the layout asked for: `wide` for `u16` row
/// and law indices (up to 65534 rows and 32767 laws, 8-byte nodes).
pub fn quantize_tree_layout(
    t: &OwnedTables<f64>,
    max_own_rows: usize,
    wide: bool,
) -> Result<Tree16Tables, QuantizeError> {
    let max_index: usize = if wide { NONE16 as usize } else { NONE as usize };
    let p = t.n_params;
    let k = t.n_outputs;
    let w = p + 1;
    if p == 0 || k == 0 {
        return Err(unsupported("explicit MPC without parameters or outputs"));
    }
    if !t.hull.is_empty() {
        return Err(unsupported(
            "the 16-bit explicit MPC takes the parameter box as the explored set (no hull rows)",
        ));
    }
    let n_rows = t.rows.len() / w;
    let n_laws = t.laws.len() / k;
    if n_rows * w != t.rows.len()
        || n_laws * k != t.laws.len()
        || t.theta_lb.len() != p
        || t.theta_ub.len() != p
        || t.bounds.len() != k
    {
        return Err(unsupported("explicit MPC tables with inconsistent lengths"));
    }
    if n_rows >= max_index || n_laws >= max_index.min(LEAF as usize) {
        return Err(unsupported(format!(
            "{n_rows} rows, {n_laws} laws: more than the layout's indices hold"
        )));
    }
    if t.rows.iter().any(|v| !v.is_finite()) {
        return Err(unsupported("a non-finite explicit MPC row"));
    }
    // Parameter scaling.
    let mut param_bits = Vec::with_capacity(p);
    let mut q_lb = Vec::with_capacity(p);
    let mut q_ub = Vec::with_capacity(p);
    for j in 0..p {
        let (lb, ub) = (t.theta_lb[j], t.theta_ub[j]);
        if !(lb.is_finite() && ub.is_finite() && lb <= ub) {
            return Err(unsupported(format!(
                "parameter {j}: box [{lb}, {ub}] is not a finite interval"
            )));
        }
        let m = lb.abs().max(ub.abs()).max(f64::MIN_POSITIVE);
        let mut e: i32 = 30;
        while e > -14 && (m * 2f64.powi(e)).round() > 32767.0 {
            e -= 1;
        }
        if (m * 2f64.powi(e)).round() > 32767.0 {
            return Err(unsupported(format!("parameter {j}: |theta| up to {m}")));
        }
        param_bits.push(e);
        q_lb.push((lb * 2f64.powi(e)).round() as i16);
        q_ub.push((ub * 2f64.powi(e)).round() as i16);
    }
    let qmax: Vec<f64> = (0..p)
        .map(|j| f64::from(q_lb[j].unsigned_abs().max(q_ub[j].unsigned_abs())))
        .collect();
    let mag: Vec<f64> = (0..p)
        .map(|j| t.theta_lb[j].abs().max(t.theta_ub[j].abs()))
        .collect();
    let enc = Enc {
        p,
        param_bits: &param_bits,
        qmax: &qmax,
        mag: &mag,
    };
    // Rows whose values are compared with other rows or given out share
    // the common scale; a row only tested against zero gets its own.
    let mut rows: Vec<Vec<f64>> = t.rows.chunks(w).map(<[f64]>::to_vec).collect();
    let mut shared = vec![false; n_rows];
    for &r in t.laws.iter().chain(t.bounds.iter().flatten()) {
        if let Some(v) = shared.get_mut(r as usize) {
            *v = true;
        }
    }
    for nd in &t.nodes {
        if nd[1] != NO_ROW {
            for &r in &nd[..2] {
                if let Some(v) = shared.get_mut(r as usize) {
                    *v = true;
                }
            }
        }
    }
    let common = |rows: &[Vec<f64>], shared: &[bool]| {
        (0..=30)
            .rev()
            .find(|&kk| (0..rows.len()).all(|r| !shared[r] || enc.fits(&rows[r], kk)))
    };
    let Some(scale) = common(&rows, &shared) else {
        return Err(unsupported(
            "explicit MPC rows too large for 16-bit gains with a 32-bit sum",
        ));
    };
    // A hyperplane `a - b` whose rounding (both rows' error bounds) moves
    // it by more than MAX_SHIFT of the box (the gradient of `a - b` is
    // small against those of `a` and `b`) gets a row of its own, tested
    // against zero in its own scale: otherwise parameters near it would
    // land on the wrong side and take a law far from theirs.
    let mut nodes_in = t.nodes.clone();
    let mut pairs: Vec<((u16, u16), f64)> = Vec::new();
    for nd in &nodes_in {
        if nd[1] == NO_ROW || pairs.iter().any(|(k, _)| *k == (nd[0], nd[1])) {
            continue;
        }
        let (Some(ra), Some(rb)) = (rows.get(nd[0] as usize), rows.get(nd[1] as usize)) else {
            return Err(unsupported("a node's row is outside the row table"));
        };
        let d: Vec<f64> = ra.iter().zip(rb).map(|(x, y)| x - y).collect();
        let shift = (enc.bound(ra, scale) + enc.bound(rb, scale)) / enc.gradient(&d);
        if shift > MAX_SHIFT {
            pairs.push(((nd[0], nd[1]), shift));
        }
    }
    // The worst first, as many as the row indices and the byte budget allow.
    pairs.sort_by(|x, y| y.1.total_cmp(&x.1));
    let mut own: std::collections::HashMap<(u16, u16), u16> = std::collections::HashMap::new();
    for ((a, b), _) in pairs.iter().take(max_own_rows) {
        if rows.len() + 1 >= max_index {
            break;
        }
        let d: Vec<f64> = rows[*a as usize]
            .iter()
            .zip(&rows[*b as usize])
            .map(|(x, y)| x - y)
            .collect();
        rows.push(d);
        shared.push(false);
        own.insert((*a, *b), (rows.len() - 1) as u16);
    }
    for nd in nodes_in.iter_mut() {
        if let Some(&r) = own.get(&(nd[0], nd[1])) {
            *nd = [r, NO_ROW, nd[2], nd[3]];
        }
    }
    let n_rows = rows.len();
    if n_rows >= max_index {
        return Err(unsupported(format!(
            "{n_rows} rows with the hyperplanes of their own: more than the layout's indices hold"
        )));
    }
    // Rows and their error bounds.
    let mut rows_bytes = Vec::new();
    let mut row_error_bound = Vec::with_capacity(n_rows);
    for (r, g) in rows.iter().enumerate() {
        let kk = if shared[r] {
            scale
        } else {
            (0..=30)
                .rev()
                .find(|&kk| enc.fits(g, kk))
                .ok_or_else(|| unsupported("a hyperplane row too large for 16-bit gains"))?
        };
        let (c, c0) = enc.quant(g, kk);
        let start = c.iter().position(|v| *v != 0).unwrap_or(p);
        rows_bytes.push(start as u8);
        rows_bytes.extend((c0 as i32).to_le_bytes());
        // Gains from the first non-zero one, then zeros (the kernel reads
        // the constant and the gains in one sweep).
        for j in 0..p {
            let v = c.get(start + j).copied().unwrap_or(0);
            rows_bytes.extend((v as i16).to_le_bytes());
        }
        row_error_bound.push(enc.bound(g, kk));
    }
    // Nodes in preorder (the `a <= b` child of an inner node is the next one).
    // Logical nodes [a, b, left, right] with NONE16 for none, encoded in
    // the layout's width below.
    let mut nodes: Vec<[u16; 4]> = Vec::new();
    let row_ix = |i: u16| -> Result<u16, QuantizeError> {
        if i == NO_ROW {
            Ok(NONE16)
        } else if (i as usize) < n_rows {
            Ok(i)
        } else {
            Err(unsupported("a node's row is outside the row table"))
        }
    };
    let mut depth = 0;
    // Iterative preorder: (original code, slot to patch with this child's index, depth).
    let mut stack: Vec<(u16, Option<usize>, usize)> = vec![(t.root, None, 0)];
    let root_code = if t.root & LEAF != 0 { t.root } else { 0 };
    while let Some((code, patch, d)) = stack.pop() {
        if code & LEAF != 0 {
            continue; // leaves are written into their parent
        }
        let nd = *nodes_in
            .get(code as usize)
            .ok_or_else(|| unsupported("a child outside the node table"))?;
        if nodes.len() >= 0x7FFF || d > nodes_in.len() {
            return Err(unsupported("explicit MPC tree too large or cyclic"));
        }
        depth = depth.max(d + 1);
        let me = nodes.len();
        if let Some(at) = patch {
            nodes[at][3] = me as u16;
        }
        let leaf = |c: u16| -> Result<u16, QuantizeError> {
            let l = c & !LEAF;
            if (l as usize) < n_laws {
                Ok(l)
            } else {
                Err(unsupported("a leaf's law is outside the law table"))
            }
        };
        let left = if nd[2] & LEAF != 0 {
            leaf(nd[2])?
        } else {
            NONE16
        };
        let right = if nd[3] & LEAF != 0 {
            LEAF | leaf(nd[3])?
        } else {
            0 // patched when the right child is written
        };
        nodes.push([row_ix(nd[0])?, row_ix(nd[1])?, left, right]);
        // Right pushed first so the left subtree comes next in preorder.
        if nd[3] & LEAF == 0 {
            stack.push((nd[3], Some(me), d + 1));
        }
        if nd[2] & LEAF == 0 {
            stack.push((nd[2], None, d + 1));
        }
    }
    let layout = Tree16Layout {
        n_params: p,
        n_outputs: k,
        n_nodes: nodes.len(),
        n_laws,
        n_rows,
        root: root_code,
        scale: scale as u8,
        wide,
    };
    // An index (row or law, NONE16 for none) in the layout's width.
    let put = |bytes: &mut Vec<u8>, v: u16| {
        if wide {
            bytes.extend(v.to_le_bytes());
        } else {
            bytes.push(if v == NONE16 { NONE } else { v as u8 });
        }
    };
    let mut bytes = Vec::with_capacity(layout.bytes());
    for j in 0..p {
        bytes.push((16 - param_bits[j]) as i8 as u8);
        bytes.extend(q_lb[j].to_le_bytes());
        bytes.extend(q_ub[j].to_le_bytes());
    }
    for n in &nodes {
        put(&mut bytes, n[0]);
        put(&mut bytes, n[1]);
        put(&mut bytes, n[2]);
        bytes.extend(n[3].to_le_bytes());
    }
    for &l in &t.laws {
        put(&mut bytes, row_ix(l)?);
    }
    let mut output_error_bound: f64 = 0.0;
    for b in &t.bounds {
        put(&mut bytes, row_ix(b[0])?);
        put(&mut bytes, row_ix(b[1])?);
    }
    for &r in t.laws.iter().chain(t.bounds.iter().flatten()) {
        if let Some(e) = row_error_bound.get(r as usize) {
            output_error_bound = output_error_bound.max(*e);
        }
    }
    bytes.extend(rows_bytes);
    if bytes.len() != layout.bytes() {
        return Err(QuantizeError::Dimension {
            what: "16-bit explicit MPC table",
            expected: layout.bytes().to_string(),
            found: bytes.len().to_string(),
        });
    }
    Ok(Tree16Tables {
        layout,
        bytes,
        param_bits,
        row_error_bound,
        output_error_bound,
        depth,
    })
}

/// How the 16-bit evaluation compares with kestrel-empc's f64 one.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Tree16Check {
    /// Parameters compared.
    pub samples: usize,
    /// Parameters where the two reach different laws.
    pub law_mismatches: usize,
    /// Largest output difference (output units: us for the tricopter).
    pub max_output_error: f64,
    /// Largest output difference where the laws agree.
    pub max_output_error_same_law: f64,
    /// Most nodes visited.
    pub max_steps: u16,
    /// Mean nodes visited.
    pub mean_steps: f64,
}

/// Evaluates the 16-bit table (the run-time code of [`Tree16`],
/// reading `q.bytes`) and kestrel-empc's f64 tree at every `theta` (which
/// must lie in the box) and compares laws and outputs.
///
/// # Errors
/// [`QuantizeError::Dimension`] if `P`, `NU` are not the tables'; an error of
/// either evaluation as [`QuantizeError::Unsupported`].
pub fn check_tree16<const P: usize, const NU: usize>(
    q: &Tree16Tables,
    reference: &OwnedTables<f64>,
    thetas: &[[f64; P]],
) -> Result<Tree16Check, QuantizeError> {
    if (q.layout.n_params, q.layout.n_outputs) != (P, NU)
        || (reference.n_params, reference.n_outputs) != (P, NU)
    {
        return Err(QuantizeError::Dimension {
            what: "check_tree16 (parameters, outputs)",
            expected: format!("({P}, {NU})"),
            found: format!("({}, {})", q.layout.n_params, q.layout.n_outputs),
        });
    }
    let err = |e: kestrel_core::Error| unsupported(format!("evaluation: {e:?}"));
    let tree = Tree16::new(&q.bytes[..], q.layout).map_err(err)?;
    let mut law = Empc16Law::<f64, _, P, NU, 256>::new(tree, 0).map_err(err)?;
    let tables = reference.tables();
    let mut c = Tree16Check::default();
    let mut steps_sum = 0.0;
    let unit = 2f64.powi(-i32::from(q.layout.scale));
    for th in thetas {
        let mut z = [0.0; NU];
        let e = kestrel_empc::evaluate(&tables, th, &mut z).map_err(err)?;
        let (qt, _) = law.quantize(th).map_err(err)?;
        let super::tree16::Raw {
            z: z16,
            law: l16,
            steps,
        } = law.evaluate_raw(&qt).map_err(err)?;
        let diff = z
            .iter()
            .zip(z16)
            .map(|(a, b)| (a - b as f64 * unit).abs())
            .fold(0.0, f64::max);
        c.samples += 1;
        c.max_output_error = c.max_output_error.max(diff);
        if l16 == e.law {
            c.max_output_error_same_law = c.max_output_error_same_law.max(diff);
        } else {
            c.law_mismatches += 1;
        }
        c.max_steps = c.max_steps.max(steps);
        steps_sum += f64::from(steps);
    }
    c.mean_steps = steps_sum / c.samples.max(1) as f64;
    Ok(c)
}

/// The Rust source of the 16-bit table: `EMPC16_LAYOUT`, `EMPC16_BYTES`,
/// `EMPC16_ROWS`, `EMPC16_DEPTH` and the bytes `EMPC16`.
pub fn tree16_source(q: &Tree16Tables) -> String {
    let l = &q.layout;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{}.\n\
         {}\n\
         /// Bytes of the 16-bit table.\npub const EMPC16_BYTES: usize = {};\n\
         /// Rows of the 16-bit table (the law's value cache).\npub const EMPC16_ROWS: usize = {};\n\
         /// Depth of the 16-bit table's tree.\npub const EMPC16_DEPTH: usize = {};\n\
         /// The 16-bit table.\n#[rustfmt::skip]\npub const EMPC16: [u8; EMPC16_BYTES] = [",
        summary_source(q),
        layout_source("EMPC16", l),
        q.bytes.len(),
        l.n_rows,
        q.depth,
    );
    byte_rows_source(&mut s, &q.bytes);
    s
}

/// The comment lines that describe a 16-bit table (no final punctuation).
fn summary_source(q: &Tree16Tables) -> String {
    let l = &q.layout;
    format!(
        "// 16-bit explicit MPC (kestrel_avr_rt::explicit::tree16, {} layout): {} nodes (depth {}),\n\
         // {} laws, {} rows, output scale 2^-{}, row error bound {:.3e} (output units)",
        if l.wide { "wide" } else { "narrow" },
        l.n_nodes,
        q.depth,
        l.n_laws,
        l.n_rows,
        l.scale,
        q.output_error_bound,
    )
}

/// The Rust source of the `{name}_LAYOUT` constant (with its doc line).
fn layout_source(name: &str, l: &Tree16Layout) -> String {
    format!(
        "/// Layout of the 16-bit table.\n\
         pub const {name}_LAYOUT: kestrel_avr_rt::explicit::tree16::Tree16Layout = kestrel_avr_rt::explicit::tree16::Tree16Layout {{\n    \
         n_params: {}, n_outputs: {}, n_nodes: {}, n_laws: {}, n_rows: {}, root: {}, scale: {}, wide: {},\n}};",
        l.n_params, l.n_outputs, l.n_nodes, l.n_laws, l.n_rows, l.root, l.scale, l.wide,
    )
}

/// Appends `bytes` as the lines of a Rust array body (24 a line) and its
/// closing `];`.
fn byte_rows_source(s: &mut String, bytes: &[u8]) {
    for row in bytes.chunks(24) {
        let line: Vec<String> = row.iter().map(|v| v.to_string()).collect();
        let _ = writeln!(s, "    {},", line.join(", "));
    }
    let _ = writeln!(s, "];");
}

/// The Rust source of a 16-bit table too large for one Rust object (over
/// 32 kB): `{NAME}_LAYOUT`, `{NAME}_BYTES`, `{NAME}_DEPTH`, the bytes in
/// statics `{NAME}_0`, `{NAME}_1`, ... of `2^chunk_bits` bytes (the last
/// shorter; on the AVR in flash, section `.text.kestrel_tables`, read with
/// `ELPM`), and `fn {name}_table() -> Option<FarChunks<..>>` joining them;
/// `what` (one line) says which controller it is, in the header.
///
/// # Errors
/// [`QuantizeError::Unsupported`] for `chunk_bits` outside `8..=14` (chunks
/// of 256 B to 16 kB) or a name that is not an upper-case identifier.
pub fn tree16_chunked_source(
    q: &Tree16Tables,
    name: &str,
    chunk_bits: u8,
    what: &str,
) -> Result<String, QuantizeError> {
    if !(8..=14).contains(&chunk_bits) {
        return Err(unsupported(format!("chunks of 2^{chunk_bits} bytes")));
    }
    if name.is_empty()
        || !name
            .chars()
            .all(|c| c.is_ascii_uppercase() || c.is_ascii_digit() || c == '_')
        || name.starts_with(|c: char| c.is_ascii_digit())
    {
        return Err(unsupported(format!("table name {name:?}")));
    }
    let l = &q.layout;
    let chunks: Vec<&[u8]> = q.bytes.chunks(1 << chunk_bits).collect();
    let lower = name.to_ascii_lowercase();
    let mut s = String::new();
    let _ = writeln!(
        s,
        "// @generated by kestrel_avr_rt::explicit::quantize::tree16_chunked_source; do not edit.\n\
         // {what}\n\
         {};\n\
         // {} bytes in {} chunks of at most {} bytes.\n\
         {}\n\
         /// Bytes of the 16-bit table.\npub const {name}_BYTES: u32 = {};\n\
         /// Depth of the 16-bit table's tree.\npub const {name}_DEPTH: usize = {};\n\
         /// Chunk size of the table: 2^bits bytes.\npub const {name}_CHUNK_BITS: u8 = {chunk_bits};\n\
         /// Chunks of the table.\npub const {name}_CHUNKS: usize = {};",
        summary_source(q),
        q.bytes.len(),
        chunks.len(),
        1usize << chunk_bits,
        layout_source(name, l),
        q.bytes.len(),
        q.depth,
        chunks.len(),
    );
    for (i, ch) in chunks.iter().enumerate() {
        let _ = writeln!(
            s,
            "/// Bytes {} to {} of the table.\n\
             #[cfg_attr(target_arch = \"avr\", unsafe(link_section = \".text.kestrel_tables\"))]\n\
             #[rustfmt::skip]\npub static {name}_{i}: [u8; {}] = [",
            i << chunk_bits,
            (i << chunk_bits) + ch.len(),
            ch.len()
        );
        byte_rows_source(&mut s, ch);
    }
    let names: Vec<String> = (0..chunks.len())
        .map(|i| format!("kestrel_avr_rt::far_table!({name}_{i})"))
        .collect();
    let _ = writeln!(
        s,
        "/// The table as one [`kestrel_avr_rt::progmem::FarChunks`] (`None` only if the chunks\n\
         /// above were edited out of shape).\n\
         pub fn {lower}_table() -> Option<kestrel_avr_rt::progmem::FarChunks<{name}_CHUNKS>> {{\n    \
         kestrel_avr_rt::progmem::FarChunks::new([\n        {},\n    ], {name}_CHUNK_BITS)\n}}",
        names.join(",\n        ")
    );
    Ok(s)
}
