//! Size guards of the commands: the libraries refuse a size whose work
//! would exceed a documented limit (a typed `TooLarge` error saying what
//! it would cost); here each refusal gets the flags that go on from it,
//! and the few sizes that are the command's own (fast-gradient
//! iterations, an explicit solve's expected time) are checked.

use kestrel_mpc::MpcError;
use kestrel_sysid::{SizedMethod, SysidError};
use kestrel_tricopter_model::ModelError;

/// Most fast-gradient iterations per solve (`fgm solve --iterations`,
/// `closed-loop --iterations`): 1,000,000. Certified counts are in the
/// tens to hundreds (26 for the thesis problem, 201 for the larger one);
/// a million iterations of a 16-variable problem take about a second per
/// parameter, and the momentum table holds one number per iteration.
pub const MAX_FGM_ITERATIONS: usize = 1_000_000;

/// Most operations of all the fast-gradient solves of one command
/// (`iterations x solves x (2 n^2 + 6 n)`): `1e12`, some minutes.
pub const MAX_FGM_FLOPS: f64 = 1e12;

/// Decision variables from which an explicit solve is announced: the
/// region count grows exponentially with them (4 variables: under a
/// second; 8: about 1,500 regions, minutes; the larger problem's 16:
/// 80,812 regions in about 70 s on 2 cores).
pub const EXPLICIT_ANNOUNCE_VARIABLES: usize = 9;

/// An MPC build error, with how to go on when the problem is too large.
pub fn mpc(e: MpcError, horizon_flag: &str) -> anyhow::Error {
    match e {
        MpcError::TooLarge { .. } => anyhow::anyhow!(
            "{e}; to go on: move blocking (--blocks, e.g. --blocks 1,1,2,6 for N = 10) so that blocks x inputs stays within {}, or a shorter {horizon_flag}",
            kestrel_mpc::MAX_DECISION_VARIABLES
        ),
        e => anyhow::Error::new(e),
    }
}

/// An identification error, with how to go on when a size is too large.
pub fn sysid(e: SysidError) -> anyhow::Error {
    match e {
        SysidError::TooLarge {
            method: SizedMethod::Pem,
            ..
        } => anyhow::anyhow!(
            "{e}; to go on: a shorter --pem-horizon or --dynamics-horizon (1 is the one-step criterion; 10 to 20 steps cover the tricopter's dynamics), a lower --order, or --method n4sid"
        ),
        SysidError::TooLarge {
            method: SizedMethod::N4sid,
            ..
        } => anyhow::anyhow!(
            "{e}; to go on: a lower --order (leave it out for the suggested one), or more data"
        ),
        SysidError::TooLarge {
            method: SizedMethod::Arx,
            ..
        } => anyhow::anyhow!(
            "{e}; to go on: fewer lags (--horizon is the VARX or ARX lags of --method pbsid, arx and armax)"
        ),
        e => anyhow::Error::new(e),
    }
}

/// A simulation error, with how to go on when the flight is too long.
pub fn simulation(e: ModelError) -> anyhow::Error {
    match e {
        ModelError::TooLarge { .. } => anyhow::anyhow!(
            "{e}; to go on: a shorter --seconds (at most {} s; fly several seeds for more data) or a coarser --dt (the default 0.001 s)",
            kestrel_tricopter_model::MAX_SIM_SECONDS
        ),
        e => anyhow::Error::new(e),
    }
}

/// Refuses more than [`MAX_FGM_ITERATIONS`] iterations, or more than
/// [`MAX_FGM_FLOPS`] operations for `solves` solves of `n` variables,
/// saying what they would cost.
pub fn fgm_iterations(iterations: usize, n: usize, solves: usize) -> anyhow::Result<()> {
    // One iteration: a matrix-vector product and the momentum step.
    let flops = iterations as f64 * solves.max(1) as f64 * (2.0 * (n * n) as f64 + 6.0 * n as f64);
    if iterations <= MAX_FGM_ITERATIONS && flops <= MAX_FGM_FLOPS {
        return Ok(());
    }
    anyhow::bail!(
        "--iterations {iterations}: at most {MAX_FGM_ITERATIONS} and {MAX_FGM_FLOPS:.0e} operations in all; {} solve(s) of {n} variables would take about {flops:.0e} operations and a momentum table of {}; `kestrel fgm certify` gives the count that reaches a tolerance (tens to hundreds), take that",
        solves.max(1),
        kestrel_mpc::human_bytes(8.0 * iterations as f64)
    )
}

/// Announces an explicit solve of `n` variables and `m` constraints
/// that may take long (from [`EXPLICIT_ANNOUNCE_VARIABLES`] variables),
/// with how to go on instead.
pub fn announce_explicit(n: usize, m: usize, alternatives: &str) {
    if n >= EXPLICIT_ANNOUNCE_VARIABLES {
        eprintln!(
            "note: explicit MPC of {n} variables and {m} constraints: the number of regions grows exponentially with the variables; 16 variables (the larger problem) took about 70 s for 80,812 regions on 2 cores, and the exploration stops at {} regions. Ctrl-C stops it; {alternatives}",
            kestrel_empc::Settings::default().max_regions
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn iterations_beyond_the_limit_are_refused_with_their_cost() {
        assert!(fgm_iterations(201, 16, 100).is_ok());
        assert!(fgm_iterations(1_000_000, 1000, 200).is_err());
        let e = fgm_iterations(1_000_000_000, 4, 1).unwrap_err().to_string();
        assert!(e.contains("8.0 GB") && e.contains("fgm certify"), "{e}");
    }
}
