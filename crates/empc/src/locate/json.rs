//! The candidate-list tables as JSON (for a solution file) and their index
//! checks.

use crate::error::EmpcError;
use crate::eval::{WIDE_LEAF, WIDE_NO_ROW};
use crate::locate::tables::ListTables;
use kestrel_core::formats::FormatError;
use kestrel_core::formats::json::{self, Object};
use serde_json::{Value, json};

/// The keys of the index tables and their row widths (0: a flat list).
const INDEX_KEYS: [(&str, usize); 9] = [
    ("nodes", 3),
    ("leaves", 3),
    ("entries", 0),
    ("region_start", 0),
    ("facets", 0),
    ("region_law", 0),
    ("hyperplanes", 2),
    ("laws", 0),
    ("bounds", 2),
];

/// An error naming the key.
fn invalid(key: &str, what: impl Into<String>) -> EmpcError {
    FormatError::invalid(format!("lists.{key}"), what.into()).into()
}

/// A non-negative integer below 2^32.
fn index(v: &Value, key: &str) -> Result<u32, EmpcError> {
    v.as_u64()
        .and_then(|x| u32::try_from(x).ok())
        .ok_or_else(|| invalid(key, "an index (integer in 0..2^32)"))
}

/// The flat list of indices under `key` (rows of `width` flattened).
fn indices(obj: &Object, key: &str, width: usize) -> Result<Vec<u32>, EmpcError> {
    let arr = obj
        .get(key)
        .and_then(Value::as_array)
        .ok_or_else(|| invalid(key, "an array"))?;
    let mut out = Vec::with_capacity(arr.len() * width.max(1));
    for v in arr {
        if width == 0 {
            out.push(index(v, key)?);
        } else {
            let row = v
                .as_array()
                .filter(|r| r.len() == width)
                .ok_or_else(|| invalid(key, format!("rows of {width} indices")))?;
            for x in row {
                out.push(index(x, key)?);
            }
        }
    }
    Ok(out)
}

/// Rows of `width` as a `Vec<[u32; N]>`.
fn rows_of<const N: usize>(flat: &[u32]) -> Vec<[u32; N]> {
    flat.chunks_exact(N)
        .map(|c| {
            let mut r = [0; N];
            r.copy_from_slice(c);
            r
        })
        .collect()
}

impl ListTables<f64> {
    /// The tables as a JSON object: `n_params`, `n_outputs`, `root`, the
    /// index tables (`nodes` `[[h, below, above]]`, `leaves` `[[first,
    /// end, law]]`, `entries`, `region_start`, `facets`, `region_law`,
    /// `hyperplanes` `[[r1, r2]]`, `laws`, `bounds` `[[lower, upper]]`;
    /// leaf and side bit `2^31`, no row `2^32 - 1`) and the numbers
    /// (`rows`, `hull` as rows of `p + 1`, `theta_lb`, `theta_ub`).
    pub fn to_json(&self) -> Value {
        let w = self.n_params + 1;
        let rows = |v: &[f64]| Value::Array(v.chunks(w).map(|r| json!(r)).collect());
        json!({
            "n_params": self.n_params,
            "n_outputs": self.n_outputs,
            "root": self.root,
            "nodes": self.nodes,
            "leaves": self.leaves,
            "entries": self.entries,
            "region_start": self.region_start,
            "facets": self.facets,
            "region_law": self.region_law,
            "hyperplanes": self.hyperplanes,
            "laws": self.laws,
            "bounds": self.bounds,
            "rows": rows(&self.rows),
            "hull": rows(&self.hull),
            "theta_lb": self.theta_lb,
            "theta_ub": self.theta_ub,
        })
    }

    /// Reads tables written by [`ListTables::to_json`] and checks them
    /// ([`ListTables::check`]); every error names its key.
    pub fn from_json(v: &Value) -> Result<ListTables<f64>, EmpcError> {
        let obj = v
            .as_object()
            .ok_or_else(|| invalid("", "an object with the candidate-list tables"))?;
        let size = |key: &str| -> Result<usize, EmpcError> {
            obj.get(key)
                .and_then(Value::as_u64)
                .and_then(|x| usize::try_from(x).ok())
                .filter(|&x| x >= 1)
                .ok_or_else(|| invalid(key, "a positive integer"))
        };
        let (p, k) = (size("n_params")?, size("n_outputs")?);
        let mut idx = INDEX_KEYS
            .iter()
            .map(|&(key, width)| indices(obj, key, width))
            .collect::<Result<Vec<_>, _>>()?
            .into_iter();
        let mut next = || idx.next().unwrap_or_default();
        let numbers = |key: &str| -> Result<Vec<f64>, EmpcError> {
            let val = obj
                .get(key)
                .ok_or_else(|| invalid(key, "rows of numbers"))?;
            let m = json::matrix_value(val, &format!("lists.{key}"), None, Some(p + 1))?;
            Ok((0..m.nrows())
                .flat_map(|i| (0..=p).map(move |j| (i, j)))
                .map(|(i, j)| m[(i, j)])
                .collect())
        };
        let t = ListTables {
            n_params: p,
            n_outputs: k,
            root: index(obj.get("root").unwrap_or(&Value::Null), "root")?,
            nodes: rows_of(&next()),
            leaves: rows_of(&next()),
            entries: next(),
            region_start: next(),
            facets: next(),
            region_law: next(),
            hyperplanes: rows_of(&next()),
            laws: next(),
            bounds: rows_of(&next()),
            rows: numbers("rows")?,
            hull: numbers("hull")?,
            theta_lb: json::vector(obj, "theta_lb", Some(p))?
                .iter()
                .copied()
                .collect(),
            theta_ub: json::vector(obj, "theta_ub", Some(p))?
                .iter()
                .copied()
                .collect(),
        };
        t.check()?;
        Ok(t)
    }

    /// Checks every index against its table, and that every node's
    /// children come after it (no cycle): the evaluation of checked tables
    /// meets no [`Error::OutOfRange`](kestrel_core::Error::OutOfRange).
    pub fn check(&self) -> Result<(), EmpcError> {
        let n_rows = self.rows.len() / (self.n_params + 1);
        let n_laws = self.laws.len() / self.n_outputs.max(1);
        let n_regions = self.region_law.len();
        let row_ok = |r: u32| r == WIDE_NO_ROW || (r as usize) < n_rows;
        let code_ok = |c: u32, after: usize| {
            if c & WIDE_LEAF != 0 {
                ((c & !WIDE_LEAF) as usize) < self.leaves.len()
            } else {
                (c as usize) < self.nodes.len() && c as usize > after
            }
        };
        if !self.rows.len().is_multiple_of(self.n_params + 1)
            || !self.laws.len().is_multiple_of(self.n_outputs.max(1))
        {
            return Err(invalid("rows", "whole rows and laws"));
        }
        if self.bounds.len() != self.n_outputs || self.bounds.iter().flatten().any(|&r| !row_ok(r))
        {
            return Err(invalid("bounds", "one row pair per output"));
        }
        if !(self.root & WIDE_LEAF != 0 && code_ok(self.root, 0)
            || self.root & WIDE_LEAF == 0 && (self.root as usize) < self.nodes.len())
        {
            return Err(invalid("root", "a node or leaf code"));
        }
        for (i, n) in self.nodes.iter().enumerate() {
            if n[0] as usize >= self.hyperplanes.len() || !code_ok(n[1], i) || !code_ok(n[2], i) {
                return Err(invalid("nodes", format!("node {i}: indices out of range")));
            }
        }
        for (i, l) in self.leaves.iter().enumerate() {
            if l[0] > l[1] || l[1] as usize > self.entries.len() || l[2] as usize >= n_laws {
                return Err(invalid("leaves", format!("leaf {i}: indices out of range")));
            }
        }
        if self.entries.iter().any(|&r| r as usize >= n_regions) {
            return Err(invalid("entries", "region indices"));
        }
        let starts_ok = self.region_start.len() == n_regions + 1
            && self.region_start.first() == Some(&0)
            && self.region_start.windows(2).all(|w| w[0] <= w[1])
            && self
                .region_start
                .last()
                .is_some_and(|&e| e as usize == self.facets.len());
        if !starts_ok {
            return Err(invalid("region_start", "increasing offsets into facets"));
        }
        if self
            .facets
            .iter()
            .any(|&f| (f & !WIDE_LEAF) as usize >= self.hyperplanes.len())
        {
            return Err(invalid("facets", "hyperplane indices"));
        }
        if self.region_law.iter().any(|&l| l as usize >= n_laws) {
            return Err(invalid("region_law", "law indices"));
        }
        if self
            .hyperplanes
            .iter()
            .any(|h| h[0] == WIDE_NO_ROW || !h.iter().all(|&r| row_ok(r)))
        {
            return Err(invalid("hyperplanes", "row indices"));
        }
        if self.laws.iter().any(|&r| r == WIDE_NO_ROW || !row_ok(r)) {
            return Err(invalid("laws", "row indices"));
        }
        if !self.hull.len().is_multiple_of(self.n_params + 1) {
            return Err(invalid("hull", "whole rows"));
        }
        Ok(())
    }
}
