//! Checks of the data and the start: a start that hovers, and the thrust
//! and drag constants from the measured operating point.

use crate::error::{sysid_dim, sysid_invalid};
use crate::ident::greybox::model::grey_box_model;
use crate::ident::greybox::spec::GreyBoxSpec;
use kestrel_sysid::{IoData, Result, SysidError};
use kestrel_tricopter_model::{GreyBoxParams, Params};

pub(super) fn check_data(data: &IoData, nu: usize, ny: usize) -> Result<()> {
    if data.nu() != nu {
        return Err(sysid_dim("data inputs vs grey-box model", nu, data.nu()));
    }
    if data.ny() != ny {
        return Err(sysid_dim("data outputs vs grey-box model", ny, data.ny()));
    }
    for (ei, e) in data.experiments().iter().enumerate() {
        for (what, m, names) in [
            ("input", &e.u, data.input_names()),
            ("output", &e.y, data.output_names()),
        ] {
            for t in 0..m.nrows() {
                for j in 0..m.ncols() {
                    if !m[(t, j)].is_finite() {
                        return Err(SysidError::NonFinite {
                            what: names
                                .get(j)
                                .cloned()
                                .unwrap_or_else(|| format!("{what} {j}")),
                            experiment: ei,
                            sample: t,
                        });
                    }
                }
            }
        }
    }
    Ok(())
}

/// The initial guess, or (when it cannot hover and `k_tau` is free) the
/// guess with `k_tau` halved until it can.
pub(super) fn feasible_start(
    initial: &GreyBoxParams,
    spec: &GreyBoxSpec,
    ts: f64,
) -> Result<(GreyBoxParams, bool)> {
    let first = match grey_box_model(initial, spec, ts) {
        Ok(_) => return Ok((*initial, false)),
        Err(e) => e,
    };
    let ik = 4; // k_tau
    if spec.free[ik] {
        let mut g = *initial;
        for _ in 0..60 {
            g.k_tau *= 0.5;
            if g.k_tau < spec.lower.k_tau {
                break;
            }
            if grey_box_model(&g, spec, ts).is_ok() {
                return Ok((g, true));
            }
        }
    }
    Err(sysid_invalid(format!(
        "the initial grey-box parameters give no model ({first}){}",
        if spec.free[ik] {
            "; halving k_tau did not help"
        } else {
            ""
        }
    )))
}

/// The thrust and drag constants `k_t`, `k_tau` at which the aircraft of
/// `base` with the other parameters of `g` hovers at the measured
/// operating point `u0 = [pwm1, pwm2, pwm3, servo]` (us): the mean ESC
/// pulse is the hover throttle (rotor speed, hence `k_t = T0 / w0^2` with
/// the known mass) and the servo pulse the tilt that cancels the rotors'
/// reaction torque (hence `k_tau / k_t`). Inertias and actuator constants
/// do not enter the trim, so this is independent of them.
///
/// A closed-form start (`3 k_t w0^2 = m g`, `3 k_tau = k_t l sin(alpha0)`)
/// polished by a damped Newton iteration on the full trim
/// ([`kestrel_tricopter_model::Tricopter::trim_hover`]) in log scale to
/// `1e-6` us. Errors for non-finite pulses, a throttle at or below
/// 1000 us, or no convergence.
pub fn thrust_and_drag_from_trim(
    base: &Params,
    g: &GreyBoxParams,
    u0: &[f64; 4],
) -> Result<GreyBoxParams> {
    if !u0.iter().all(|v| v.is_finite()) {
        return Err(sysid_invalid(format!(
            "operating point {u0:?} is not finite"
        )));
    }
    let thr = (u0[0] + u0[1] + u0[2]) / 3.0;
    let w0 = base.rotor_speed_for_pwm(thr);
    if w0 <= 0.0 {
        return Err(sysid_invalid(format!(
            "operating point throttle {thr} us gives no rotor speed"
        )));
    }
    let alpha = base.servo_gain * (u0[3] - base.servo_center);
    let mut out = *g;
    out.k_t = base.mass * base.gravity / (3.0 * w0 * w0);
    out.k_tau = (out.k_t * base.arm_length * alpha.sin().abs() / 3.0).max(1e-6 * out.k_t);
    let resid = |kt: f64, ktau: f64| -> Option<[f64; 2]> {
        let mut q = *g;
        q.k_t = kt;
        q.k_tau = ktau;
        let model = kestrel_tricopter_model::Tricopter::new(q.apply(base)).ok()?;
        let t = model.trim_hover().ok()?;
        Some([t.throttle - thr, t.input[3] - u0[3]])
    };
    let mut z = [out.k_t.ln(), out.k_tau.ln()];
    let fail = || {
        sysid_invalid(format!(
            "no k_t, k_tau make the aircraft hover at the operating point {u0:?}"
        ))
    };
    let mut f = resid(z[0].exp(), z[1].exp()).ok_or_else(fail)?;
    for _ in 0..50 {
        if f[0].abs().max(f[1].abs()) < 1e-6 {
            out.k_t = z[0].exp();
            out.k_tau = z[1].exp();
            return Ok(out);
        }
        let h = 1e-6;
        let mut jac = [[0.0; 2]; 2];
        for c in 0..2 {
            let mut zp = z;
            let mut zm = z;
            zp[c] += h;
            zm[c] -= h;
            let fp = resid(zp[0].exp(), zp[1].exp()).ok_or_else(fail)?;
            let fm = resid(zm[0].exp(), zm[1].exp()).ok_or_else(fail)?;
            for r in 0..2 {
                jac[r][c] = (fp[r] - fm[r]) / (2.0 * h);
            }
        }
        let det = jac[0][0] * jac[1][1] - jac[0][1] * jac[1][0];
        if !(det.abs() > 0.0 && det.is_finite()) {
            return Err(fail());
        }
        let step = [
            -(jac[1][1] * f[0] - jac[0][1] * f[1]) / det,
            -(-jac[1][0] * f[0] + jac[0][0] * f[1]) / det,
        ];
        let mut s = 1.0;
        loop {
            let zt = [z[0] + s * step[0], z[1] + s * step[1]];
            if let Some(ft) = resid(zt[0].exp(), zt[1].exp())
                && ft[0].abs().max(ft[1].abs()) < f[0].abs().max(f[1].abs())
            {
                z = zt;
                f = ft;
                break;
            }
            s *= 0.5;
            if s < 1e-6 {
                return Err(fail());
            }
        }
    }
    Err(fail())
}
