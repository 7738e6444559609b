//! Readers of the `kestrel mpc` constraint flags: comma separated bound
//! lists (`inf`, `-inf` or an empty entry for no bound), the soft-bound
//! families, the input target, extra parameters and the terminal set.
//! Every error names the flag.

use anyhow::{Context, bail};
use kestrel_core::formats::json;
use kestrel_mpc::{InputTarget, Parameter, SoftPenalty, TerminalSet};
use nalgebra::DVector;
use std::path::Path;

/// Which side of a bound a list gives: an empty entry is no bound
/// (`-inf` below, `+inf` above).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    /// A lower bound (`--y-min`, ...).
    Lower,
    /// An upper bound (`--y-max`, ...).
    Upper,
}

/// The entries a list is about, for messages: `what` is the singular
/// (`"output"`, `"state"`, `"input"`), `names` the model's names (may be
/// empty).
#[derive(Clone, Copy, Debug)]
pub struct Entries<'a> {
    /// Singular noun of one entry.
    pub what: &'a str,
    /// The model's names of the entries, or empty.
    pub names: &'a [String],
    /// How many entries the list must have.
    pub n: usize,
}

impl Entries<'_> {
    /// `"output 2 (velocity)"` (1-based).
    pub fn label(&self, i: usize) -> String {
        match self.names.get(i) {
            Some(name) => format!("{} {} ({name})", self.what, i + 1),
            None => format!("{} {}", self.what, i + 1),
        }
    }

    /// `"entry 2 (velocity)"` (1-based; the name when the model has one).
    pub fn entry(&self, i: usize) -> String {
        match self.names.get(i) {
            Some(name) => format!("entry {} ({name})", i + 1),
            None => format!("entry {}", i + 1),
        }
    }

    /// `"the model has 2 outputs (position, velocity)"`.
    fn count(&self) -> String {
        let plural = if self.n == 1 { "" } else { "s" };
        if self.names.len() == self.n && self.n > 0 {
            format!(
                "the model has {} {}{plural}: {}",
                self.n,
                self.what,
                self.names.join(", ")
            )
        } else {
            format!("the model has {} {}{plural}", self.n, self.what)
        }
    }
}

/// Reads a comma separated list of `entries.n` bounds given to `flag`:
/// numbers, `inf`/`-inf`, or an empty entry for no bound on that side.
pub fn bound_list(
    text: &str,
    flag: &str,
    entries: Entries<'_>,
    side: Side,
) -> anyhow::Result<DVector<f64>> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    if parts.len() != entries.n {
        bail!(
            "{flag} {text}: expected {} comma separated entr{} ({}; inf, -inf or an empty entry for no bound), found {}",
            entries.n,
            if entries.n == 1 { "y" } else { "ies" },
            entries.count(),
            parts.len()
        );
    }
    let none = match side {
        Side::Lower => f64::NEG_INFINITY,
        Side::Upper => f64::INFINITY,
    };
    let mut v = DVector::zeros(entries.n);
    for (i, part) in parts.iter().enumerate() {
        v[i] = if part.is_empty() {
            none
        } else {
            let x: f64 = part.parse().map_err(|_| {
                anyhow::anyhow!(
                    "{flag}: {} is {part:?}, not a number (inf, -inf or an empty entry is no bound)",
                    entries.entry(i)
                )
            })?;
            if x.is_nan() {
                bail!("{flag}: {} is NaN", entries.entry(i));
            }
            if x.is_infinite() && x != none {
                let (wrong, right) = match side {
                    Side::Lower => ("inf", "-inf"),
                    Side::Upper => ("-inf", "inf"),
                };
                bail!(
                    "{flag}: {} is {wrong}, which no value satisfies; {right} or an empty entry is no bound",
                    entries.entry(i)
                );
            }
            x
        };
    }
    Ok(v)
}

/// Reads an optional lower and upper list (`min_flag`, `max_flag`) into
/// bounds, the missing side unbounded; `None` when neither is given.
/// Refuses a lower bound above its upper bound.
pub fn bound_pair(
    min: Option<&str>,
    max: Option<&str>,
    (min_flag, max_flag): (&str, &str),
    entries: Entries<'_>,
) -> anyhow::Result<Option<(DVector<f64>, DVector<f64>)>> {
    if min.is_none() && max.is_none() {
        return Ok(None);
    }
    let lower = match min {
        Some(t) => bound_list(t, min_flag, entries, Side::Lower)?,
        None => DVector::from_element(entries.n, f64::NEG_INFINITY),
    };
    let upper = match max {
        Some(t) => bound_list(t, max_flag, entries, Side::Upper)?,
        None => DVector::from_element(entries.n, f64::INFINITY),
    };
    if let Some(i) = (0..entries.n).find(|&i| lower[i] > upper[i]) {
        bail!(
            "infeasible {} bounds: {min_flag} above {max_flag} for {}: {} > {}",
            entries.what,
            entries.label(i),
            lower[i],
            upper[i]
        );
    }
    Ok(Some((lower, upper)))
}

/// The input-move bounds of `--du-max` and `--du-min` (default
/// `-du-max`): `du-max >= 0 >= du-min` entry by entry.
pub fn move_bounds(
    du_max: &str,
    du_min: Option<&str>,
    entries: Entries<'_>,
) -> anyhow::Result<(DVector<f64>, DVector<f64>)> {
    let upper = bound_list(du_max, "--du-max", entries, Side::Upper)?;
    if let Some(i) = (0..entries.n).find(|&i| upper[i] < 0.0) {
        bail!(
            "--du-max: {} is {}, below zero; a move bound is at least 0 (0 holds that input still, inf leaves it free)",
            entries.entry(i),
            upper[i]
        );
    }
    let lower = match du_min {
        Some(t) => bound_list(t, "--du-min", entries, Side::Lower)?,
        None => -&upper,
    };
    if let Some(i) = (0..entries.n).find(|&i| lower[i] > 0.0) {
        bail!(
            "--du-min: {} is {}, above zero; the largest move down is at most 0 (e.g. -{} for a symmetric limit)",
            entries.entry(i),
            lower[i],
            lower[i]
        );
    }
    Ok((lower, upper))
}

/// Which bound families `--soft` makes soft.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SoftFamilies {
    /// Output bounds (`--y-min/--y-max`): `y`.
    pub outputs: bool,
    /// State bounds (`--state-min/--state-max`): `x`.
    pub states: bool,
    /// Input-move bounds (`--du-max/--du-min`): `du`.
    pub moves: bool,
}

/// The value of `--soft` with no list: every non-input bound family.
pub const SOFT_DEFAULT: &str = "y,x";

/// Reads `--soft`'s list: `y` (outputs), `x` (states), `du` (input moves).
pub fn soft_families(text: &str) -> anyhow::Result<SoftFamilies> {
    let mut f = SoftFamilies::default();
    for part in text.split(',').map(str::trim) {
        match part {
            "y" => f.outputs = true,
            "x" => f.states = true,
            "du" => f.moves = true,
            other => bail!(
                "--soft {text}: unknown bound family {other:?}; expected a comma separated list of y (output bounds), x (state bounds) and du (input-move bounds); --soft alone is {SOFT_DEFAULT} (input bounds stay hard)"
            ),
        }
    }
    Ok(f)
}

/// The penalty of soft bounds: `--soft-weight` (> 0) and `--soft-linear`
/// (>= 0), each defaulting to [`SoftPenalty::default`].
pub fn soft_penalty(weight: Option<f64>, linear: Option<f64>) -> anyhow::Result<SoftPenalty> {
    let d = SoftPenalty::default();
    let quadratic = weight.unwrap_or(d.quadratic);
    let linear = linear.unwrap_or(d.linear);
    if !(quadratic.is_finite() && quadratic > 0.0) {
        bail!(
            "--soft-weight {quadratic}: the quadratic penalty of a slack must be a finite number above zero (it keeps the QP's Hessian positive definite; default {})",
            d.quadratic
        );
    }
    if !(linear.is_finite() && linear >= 0.0) {
        bail!(
            "--soft-linear {linear}: the linear (exact) penalty of a slack must be a finite number, at least zero (default {})",
            d.linear
        );
    }
    Ok(SoftPenalty { quadratic, linear })
}

/// Checks `--preview P` against the horizon: `1 <= P <= N`.
pub fn preview(p: usize, horizon: usize) -> anyhow::Result<usize> {
    if horizon == 0 {
        bail!("--horizon 0: the prediction horizon must be at least one step");
    }
    if p == 0 || p > horizon {
        bail!(
            "--preview {p}: the reference steps in theta must be between 1 (a constant reference) and the horizon (--horizon {horizon})"
        );
    }
    Ok(p)
}

/// Reads `--u-target`: `param` (an input target in theta) or `nu` numbers
/// (deviations from u0).
pub fn input_target(text: &str, entries: Entries<'_>) -> anyhow::Result<InputTarget> {
    if text.trim() == "param" {
        return Ok(InputTarget::Parameter);
    }
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    if parts.len() != entries.n {
        bail!(
            "--u-target {text}: expected `param` or {} comma separated number{} ({}), found {} entries",
            entries.n,
            if entries.n == 1 { "" } else { "s" },
            entries.count(),
            parts.len()
        );
    }
    let mut v = DVector::zeros(entries.n);
    for (i, part) in parts.iter().enumerate() {
        v[i] = part
            .parse::<f64>()
            .ok()
            .filter(|x| x.is_finite())
            .ok_or_else(|| {
                anyhow::anyhow!(
                    "--u-target: {} is {part:?}, not a finite number",
                    entries.entry(i)
                )
            })?;
    }
    Ok(InputTarget::Fixed(v))
}

/// Reads one `--param NAME=MIN:MAX`.
pub fn parameter(text: &str) -> anyhow::Result<Parameter> {
    let bad = || {
        anyhow::anyhow!(
            "--param {text}: expected NAME=MIN:MAX with finite MIN <= MAX (e.g. --param load=0:1)"
        )
    };
    let (name, range) = text.split_once('=').ok_or_else(bad)?;
    let (lo, hi) = range.split_once(':').ok_or_else(bad)?;
    let (lo, hi): (f64, f64) = (
        lo.trim().parse().map_err(|_| bad())?,
        hi.trim().parse().map_err(|_| bad())?,
    );
    let name = name.trim();
    if name.is_empty() || !lo.is_finite() || !hi.is_finite() || lo > hi {
        return Err(bad());
    }
    Ok(Parameter::new(name, lo, hi))
}

/// Reads `--terminal-set FILE`: a JSON object `{"a": rows, "b": [..]}`
/// with `nx` columns in `a` and one entry of `b` per row.
pub fn terminal_set(path: &Path, nx: usize) -> anyhow::Result<TerminalSet> {
    let what = || format!("--terminal-set {}", path.display());
    let text = std::fs::read_to_string(path).with_context(what)?;
    let obj = json::parse_object(&text).with_context(what)?;
    let a = json::matrix(&obj, "a", None, Some(nx)).with_context(what)?;
    let b = json::vector(&obj, "b", Some(a.nrows())).with_context(what)?;
    if a.nrows() == 0 {
        bail!("{}: \"a\" has no rows", what());
    }
    Ok(TerminalSet { a, b })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn outputs(names: &[String], n: usize) -> Entries<'_> {
        Entries {
            what: "output",
            names,
            n,
        }
    }

    #[test]
    fn bound_lists_read_infinities_and_empty_entries() {
        let names = vec!["p".to_string(), "q".to_string(), "r".to_string()];
        let e = outputs(&names, 3);
        let v = bound_list("-1, ,-inf", "--y-min", e, Side::Lower).unwrap();
        assert_eq!(v.as_slice(), [-1.0, f64::NEG_INFINITY, f64::NEG_INFINITY]);
        let v = bound_list("inf,2,", "--y-max", e, Side::Upper).unwrap();
        assert_eq!(v.as_slice(), [f64::INFINITY, 2.0, f64::INFINITY]);
        let err = bound_list("1,2", "--y-min", e, Side::Lower).unwrap_err();
        assert!(err.to_string().contains("--y-min 1,2: expected 3"), "{err}");
        assert!(err.to_string().contains("3 outputs: p, q, r"), "{err}");
        let err = bound_list("1,inf,2", "--y-min", e, Side::Lower).unwrap_err();
        assert!(err.to_string().contains("entry 2 (q) is inf"), "{err}");
        let err = bound_list("1,x,2", "--y-max", e, Side::Upper).unwrap_err();
        assert!(err.to_string().contains("not a number"), "{err}");
        let err = bound_pair(Some("0,0,1"), Some("1,1,0"), ("--y-min", "--y-max"), e)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("--y-min above --y-max for output 3 (r)"),
            "{err}"
        );
        assert!(bound_pair(None, None, ("a", "b"), e).unwrap().is_none());
    }

    #[test]
    fn move_bounds_soft_and_parameters_check_their_ranges() {
        let e = Entries {
            what: "input",
            names: &[],
            n: 2,
        };
        let (lo, hi) = move_bounds("1,inf", None, e).unwrap();
        assert_eq!((lo[0], hi[1]), (-1.0, f64::INFINITY));
        assert!(lo[1].is_infinite() && lo[1] < 0.0);
        let err = move_bounds("-1,1", None, e).unwrap_err().to_string();
        assert!(
            err.contains("--du-max") && err.contains("below zero"),
            "{err}"
        );
        let err = move_bounds("1,1", Some("0.5,-1"), e)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("--du-min") && err.contains("above zero"),
            "{err}"
        );
        assert_eq!(
            soft_families(SOFT_DEFAULT).unwrap(),
            SoftFamilies {
                outputs: true,
                states: true,
                moves: false
            }
        );
        assert!(soft_families("u").is_err());
        assert!(
            soft_penalty(Some(0.0), None)
                .unwrap_err()
                .to_string()
                .contains("--soft-weight 0")
        );
        assert!(
            soft_penalty(None, Some(-1.0))
                .unwrap_err()
                .to_string()
                .contains("--soft-linear")
        );
        // The defaults the help text of --soft-weight and --soft-linear states.
        assert_eq!(
            soft_penalty(None, None).unwrap(),
            SoftPenalty {
                quadratic: 1e2,
                linear: 1e4
            }
        );
        assert!(
            preview(11, 10)
                .unwrap_err()
                .to_string()
                .contains("--horizon 10")
        );
        assert!(preview(0, 10).is_err());
        assert_eq!(preview(10, 10).unwrap(), 10);
        assert_eq!(
            parameter("load=0:1.5").unwrap(),
            Parameter::new("load", 0.0, 1.5)
        );
        assert!(parameter("load=2:1").is_err() && parameter("load").is_err());
        assert_eq!(input_target("param", e).unwrap(), InputTarget::Parameter);
        assert!(
            input_target("1", e)
                .unwrap_err()
                .to_string()
                .contains("--u-target")
        );
    }
}
