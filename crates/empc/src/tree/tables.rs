//! The owned tables of the single-tree layout, `u16` or `u32` indices
//! ([`OwnedTables`], [`WideTables`], [`AnyTables`]), and the conversions
//! between the two index widths.

use crate::eval::{
    Evaluation, LEAF, NO_ROW, SliceTables, TreeIndex, WIDE_LEAF, WIDE_NO_ROW, evaluate_with,
};
use crate::tree::settings::MAX_NODES;
use kestrel_core::Scalar;

/// Owned tables of an explicit controller, in scalar `S`, with index type
/// `X`: `u16` (the default, [`LEAF`] child codes, [`NO_ROW`]) or `u32`
/// ([`WideTables`]).
#[derive(Clone, Debug, PartialEq)]
pub struct OwnedTables<S, X = u16> {
    /// Number of parameters `p`.
    pub n_params: usize,
    /// Number of outputs `k`.
    pub n_outputs: usize,
    /// The root child code.
    pub root: X,
    /// Tree nodes `[row a, row b, child if a <= b, child otherwise]`.
    pub nodes: Vec<[X; 4]>,
    /// Laws, `k` row indices each.
    pub laws: Vec<X>,
    /// Affine rows, `p + 1` entries each.
    pub rows: Vec<S>,
    /// Explored set rows, `p + 1` entries each.
    pub hull: Vec<S>,
    /// Parameter lower bounds.
    pub theta_lb: Vec<S>,
    /// Parameter upper bounds.
    pub theta_ub: Vec<S>,
    /// Per output: rows of the lower and upper bound (`X::NO_ROW`: none).
    pub bounds: Vec<[X; 2]>,
}

impl<S: Scalar, X: TreeIndex> OwnedTables<S, X> {
    /// Borrowed tables for [`crate::evaluate`].
    pub fn tables(&self) -> SliceTables<'_, S, X> {
        SliceTables {
            n_params: self.n_params,
            n_outputs: self.n_outputs,
            root: self.root,
            nodes: &self.nodes,
            laws: &self.laws,
            rows: &self.rows,
            hull: &self.hull,
            theta_lb: &self.theta_lb,
            theta_ub: &self.theta_ub,
            bounds: &self.bounds,
        }
    }
    /// The same tables in another scalar (rounded through `f64`).
    pub fn cast<T: Scalar>(&self) -> OwnedTables<T, X> {
        let c = |v: &Vec<S>| v.iter().map(|x| T::from_f64(x.to_f64())).collect();
        OwnedTables {
            n_params: self.n_params,
            n_outputs: self.n_outputs,
            root: self.root,
            nodes: self.nodes.clone(),
            laws: self.laws.clone(),
            rows: c(&self.rows),
            hull: c(&self.hull),
            theta_lb: c(&self.theta_lb),
            theta_ub: c(&self.theta_ub),
            bounds: self.bounds.clone(),
        }
    }
    /// Storage in bytes with `scalar_bytes` per number and the index
    /// type's size per index (2 for `u16`, 4 for `u32`).
    pub fn bytes(&self, scalar_bytes: usize) -> usize {
        let numbers = self.rows.len() + self.hull.len() + self.theta_lb.len() + self.theta_ub.len();
        numbers * scalar_bytes
            + core::mem::size_of::<X>()
                * (4 * self.nodes.len() + self.laws.len() + 2 * self.bounds.len())
    }
}

/// Owned tables of the wide layout (`u32` indices, [`WIDE_LEAF`] child
/// codes, [`WIDE_NO_ROW`]) in scalar `S`: the layout of trees beyond the
/// [`MAX_NODES`] the `u16` codes address, otherwise as [`OwnedTables`]
/// (the same struct with index type `u32`). Evaluated by
/// [`crate::evaluate`] through [`OwnedTables::tables`].
pub type WideTables<S> = OwnedTables<S, u32>;

/// A `u16` child code in the wide layout.
fn widen_code(c: u16) -> u32 {
    if c & LEAF != 0 {
        WIDE_LEAF | u32::from(c & !LEAF)
    } else {
        u32::from(c)
    }
}

/// A `u16` row index in the wide layout.
pub(super) fn widen_row(r: u16) -> u32 {
    if r == NO_ROW {
        WIDE_NO_ROW
    } else {
        u32::from(r)
    }
}

/// A wide child code as `u16`, if it fits.
fn narrow_code(c: u32) -> Option<u16> {
    if c & WIDE_LEAF != 0 {
        let v = u16::try_from(c & !WIDE_LEAF).ok()?;
        (v & LEAF == 0).then_some(LEAF | v)
    } else {
        u16::try_from(c).ok().filter(|v| v & LEAF == 0)
    }
}

/// A wide row index as `u16`, if it fits.
fn narrow_row(r: u32) -> Option<u16> {
    if r == WIDE_NO_ROW {
        Some(NO_ROW)
    } else {
        u16::try_from(r).ok().filter(|&v| v != NO_ROW)
    }
}

impl<S: Scalar> WideTables<S> {
    /// The same tree in the `u16` layout, if every index fits (at most
    /// [`MAX_NODES`] nodes, 32767 laws, 65534 rows); `None` otherwise.
    pub fn narrow(&self) -> Option<OwnedTables<S>> {
        let nodes = self
            .nodes
            .iter()
            .map(|n| {
                Some([
                    narrow_row(n[0])?,
                    narrow_row(n[1])?,
                    narrow_code(n[2])?,
                    narrow_code(n[3])?,
                ])
            })
            .collect::<Option<Vec<_>>>()?;
        let laws = self
            .laws
            .iter()
            .map(|&r| narrow_row(r).filter(|&v| v != NO_ROW))
            .collect::<Option<Vec<_>>>()?;
        let bounds = self
            .bounds
            .iter()
            .map(|b| Some([narrow_row(b[0])?, narrow_row(b[1])?]))
            .collect::<Option<Vec<_>>>()?;
        if nodes.len() > MAX_NODES || self.rows.len() / (self.n_params + 1) >= NO_ROW as usize {
            return None;
        }
        Some(OwnedTables {
            n_params: self.n_params,
            n_outputs: self.n_outputs,
            root: narrow_code(self.root)?,
            nodes,
            laws,
            rows: self.rows.clone(),
            hull: self.hull.clone(),
            theta_lb: self.theta_lb.clone(),
            theta_ub: self.theta_ub.clone(),
            bounds,
        })
    }
}

impl<S: Scalar> OwnedTables<S> {
    /// The same tree in the wide layout (`u32` indices).
    pub fn widen(&self) -> WideTables<S> {
        WideTables {
            n_params: self.n_params,
            n_outputs: self.n_outputs,
            root: widen_code(self.root),
            nodes: self
                .nodes
                .iter()
                .map(|n| {
                    [
                        widen_row(n[0]),
                        widen_row(n[1]),
                        widen_code(n[2]),
                        widen_code(n[3]),
                    ]
                })
                .collect(),
            laws: self.laws.iter().map(|&r| u32::from(r)).collect(),
            rows: self.rows.clone(),
            hull: self.hull.clone(),
            theta_lb: self.theta_lb.clone(),
            theta_ub: self.theta_ub.clone(),
            bounds: self
                .bounds
                .iter()
                .map(|b| [widen_row(b[0]), widen_row(b[1])])
                .collect(),
        }
    }
}

/// The tables of [`build_any`](crate::tree::build_any): the `u16` layout when the tree fits (or
/// was asked for), else the wide `u32` layout.
#[derive(Clone, Debug, PartialEq)]
pub enum AnyTables {
    /// `u16` indices, flash-ready ([`OwnedTables`]).
    Narrow(OwnedTables<f64>),
    /// `u32` indices ([`WideTables`]).
    Wide(WideTables<f64>),
}

impl AnyTables {
    /// Whether these are the wide (`u32`) tables.
    pub fn is_wide(&self) -> bool {
        matches!(self, AnyTables::Wide(_))
    }
    /// Storage in bytes with `scalar_bytes` per number (2 or 4 per index).
    pub fn bytes(&self, scalar_bytes: usize) -> usize {
        match self {
            AnyTables::Narrow(t) => t.bytes(scalar_bytes),
            AnyTables::Wide(t) => t.bytes(scalar_bytes),
        }
    }
    /// Tree nodes.
    pub fn n_nodes(&self) -> usize {
        match self {
            AnyTables::Narrow(t) => t.nodes.len(),
            AnyTables::Wide(t) => t.nodes.len(),
        }
    }
    /// Evaluates either layout in `f64`, the law index as `u32`
    /// (allocates a scratch vector: in a loop, borrow the tables and call
    /// [`crate::evaluate`]).
    pub fn evaluate_f64(
        &self,
        theta: &[f64],
        z: &mut [f64],
    ) -> Result<Evaluation<u32>, kestrel_core::Error> {
        let mut scratch = vec![0.0; theta.len()];
        match self {
            AnyTables::Narrow(t) => {
                evaluate_with(&t.tables(), theta, &mut scratch, z).map(|e| Evaluation {
                    law: u32::from(e.law),
                    outside: e.outside,
                    steps: e.steps,
                })
            }
            AnyTables::Wide(t) => evaluate_with(&t.tables(), theta, &mut scratch, z),
        }
    }
}
