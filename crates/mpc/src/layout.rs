//! Where each part of the parameter vector `theta` sits.

use core::ops::Range;

/// The layout of the parameter vector
///
/// ```text
/// theta = [x (nx); u_prev (nu_prev); r_1 .. r_P (ny each); u_target (nu_target); p (np)]
/// ```
///
/// - `x`: the state estimate the law reads;
/// - `u_prev`: the input applied last (deviation from the trim), present
///   (`nu_prev = nu`) when an input-move weight or bound is set;
/// - `r_1 .. r_P`: the output references of the preview (`P = 1`: one
///   constant reference);
/// - `u_target`: the input target, present (`nu_target = nu`) when it is a
///   parameter ([`InputTarget::Parameter`](crate::InputTarget::Parameter));
/// - `p`: the extra parameters ([`MpcSettings::parameters`](crate::MpcSettings::parameters)),
///   e.g. the thesis's throttle.
///
/// The thesis's problems are `[x; r; throttle]`. A [`kestrel_core::ControlLaw`]
/// over the problem ([`MpcLaw`](crate::MpcLaw)) reads `x` as its state and
/// everything after `u_prev` as its reference vector; it keeps `u_prev`
/// itself.
///
/// ```
/// use kestrel_mpc::ThetaLayout;
/// let l = ThetaLayout { nx: 5, nu_prev: 4, ny: 3, preview: 2, nu_target: 0, np: 1 };
/// assert_eq!(l.len(), 5 + 4 + 6 + 1);
/// assert_eq!(l.reference(1), 12..15);
/// assert_eq!(l.parameters(), 15..16);
/// assert_eq!(l.n_law_reference(), 7);
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ThetaLayout {
    /// Number of states.
    pub nx: usize,
    /// Entries of the previous input (0 or `nu`).
    pub nu_prev: usize,
    /// Outputs per reference step.
    pub ny: usize,
    /// Reference steps `P` (at least 1).
    pub preview: usize,
    /// Entries of the input target (0 or `nu`).
    pub nu_target: usize,
    /// Extra parameters.
    pub np: usize,
}

impl ThetaLayout {
    /// Length of `theta`.
    pub fn len(&self) -> usize {
        self.nx + self.nu_prev + self.ny * self.preview + self.nu_target + self.np
    }
    /// Whether `theta` is empty (never for a built problem).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// The state entries.
    pub fn state(&self) -> Range<usize> {
        0..self.nx
    }
    /// The previous input's entries (empty without input-move terms).
    pub fn previous_input(&self) -> Range<usize> {
        self.nx..self.nx + self.nu_prev
    }
    /// All reference entries, `r_1 .. r_P`.
    pub fn references(&self) -> Range<usize> {
        let s = self.nx + self.nu_prev;
        s..s + self.ny * self.preview
    }
    /// The entries of reference step `k` (`0`-based: `r_{k+1}`).
    pub fn reference(&self, k: usize) -> Range<usize> {
        let s = self.nx + self.nu_prev + k * self.ny;
        s..s + self.ny
    }
    /// The input target's entries (empty unless it is a parameter).
    pub fn input_target(&self) -> Range<usize> {
        let s = self.references().end;
        s..s + self.nu_target
    }
    /// The extra parameters' entries.
    pub fn parameters(&self) -> Range<usize> {
        let s = self.input_target().end;
        s..s + self.np
    }
    /// Number of entries a control law reads as its reference vector:
    /// everything after the state and the previous input.
    pub fn n_law_reference(&self) -> usize {
        self.len() - self.nx - self.nu_prev
    }
    /// Writes `theta = [x; u_prev; r]` where `r` holds the law's reference
    /// vector ([`ThetaLayout::n_law_reference`] entries); lengths are
    /// checked (`u_prev` must have `nu_prev` entries, none when the layout
    /// has no previous input).
    pub fn assemble_into(
        &self,
        x: &[f64],
        u_prev: &[f64],
        r: &[f64],
        theta: &mut [f64],
    ) -> Result<(), kestrel_core::Error> {
        kestrel_core::check_len(x, self.nx)?;
        kestrel_core::check_len(u_prev, self.nu_prev)?;
        kestrel_core::check_len(r, self.n_law_reference())?;
        kestrel_core::check_len(theta, self.len())?;
        theta[self.state()].copy_from_slice(x);
        theta[self.previous_input()].copy_from_slice(u_prev);
        theta[self.nx + self.nu_prev..].copy_from_slice(r);
        Ok(())
    }
}
