//! The exact MPC at the certified worst cases: kestrel-empc's complexity
//! certification of kestrel-qp's solver on the design's problem (cold
//! start; warm start from the previous period's optimal active set, in
//! any stored order, for parameter steps up to [`WARM_STEP`] of each
//! parameter's box width) gives the regions with the most iterations and
//! flops; their interior points (on a 2^-12 grid) are solved by
//! the on-target check firmware (`qp-check`, `qp16-check`), which serves
//! the host's parameters after its own samples.

use super::qp_target::{Sample, parse_result};
use super::{design, generated, host_qp_law, min_mean_max, read_frames};
use avr_tester::AvrTester;
use kestrel_avr_rt::control::LawInfo;
use kestrel_avr_rt::cycles::CycleStats;
use kestrel_avr_rt::frame::{Frame, FrameDecoder, Kind, MAX_FRAME};
use kestrel_core::ControlLaw;
use kestrel_empc::certify::{Certification, CertifySettings, certify};

/// The warm start's certified parameter step (fraction of each
/// parameter's box width per period).
const WARM_STEP: f64 = 0.05;

/// The certification of the design's problem (once per test binary).
fn certification() -> &'static Certification {
    static C: std::sync::OnceLock<Certification> = std::sync::OnceLock::new();
    C.get_or_init(|| {
        let settings = CertifySettings {
            warm_step: Some(WARM_STEP),
            warm_any_order: true,
            ..CertifySettings::default()
        };
        let t0 = std::time::Instant::now();
        let c = certify(&design().problem, &settings, &mut |_| {}).expect("certification");
        println!(
            "certified (design's problem, {:.1} s): cold worst {} iterations, {} flops, {} regions; warm (step {WARM_STEP}) worst {} iterations, {} flops",
            t0.elapsed().as_secs_f64(),
            c.cold.worst_iterations,
            c.cold.worst_flops,
            c.cold.regions,
            c.warm.as_ref().map_or(0, |w| w.worst_iterations),
            c.warm.as_ref().map_or(0, |w| w.worst_flops),
        );
        // The firmware's iteration caps are the certified worst case: of
        // warm and cold starts for the qp builds (warm-started), of cold
        // starts for the qp16 builds (cold every period).
        let worst = c
            .cold
            .worst_iterations
            .max(c.warm.as_ref().map_or(0, |w| w.worst_iterations));
        assert_eq!(worst, super::QP_MAX_ITERATIONS, "the qp builds' cap is not the certified worst case");
        assert_eq!(
            super::qp16_max_iterations(),
            c.cold.worst_iterations,
            "the qp16 builds' cap is not the certified cold worst case"
        );
        c
    })
}

/// `v` on a grid of 2^-12 (exact in f32 up to 2,048 and in Q15.16: the
/// firmware solves exactly this parameter in both builds).
fn grid(v: f64) -> f32 {
    ((v * 4096.0).round() / 4096.0) as f32
}

/// Solves `theta` on the target (cold, or `warm` from the previous
/// request's active set).
fn solve(
    avr: &mut AvrTester,
    dec: &mut FrameDecoder,
    index: u16,
    theta: [f32; generated::NP],
    warm: bool,
) -> Sample {
    let index = index | if warm { 0x8000 } else { 0 };
    let mut payload = index.to_le_bytes().to_vec();
    for t in theta {
        payload.extend_from_slice(&t.to_le_bytes());
    }
    let mut wire = [0u8; MAX_FRAME];
    let n = Frame::new(Kind::Bench, 0, &payload)
        .unwrap()
        .encode(&mut wire)
        .unwrap();
    avr.uart0().write(&wire[..n]);
    for _ in 0..200 {
        avr.run_for_ms(1);
        for f in read_frames(avr, dec) {
            let p = f.payload();
            if f.kind == Kind::Bench && p.len() == 24 && u16::from_le_bytes([p[0], p[1]]) == index {
                return parse_result(p, theta);
            }
        }
    }
    panic!("no answer to the parameter request {index:#x}");
}

/// A certified case: its name, the previous parameter of a warm start,
/// the parameter and the certified iterations.
type Case<'a> = (&'a str, Option<Vec<f64>>, Vec<f64>, usize);

/// Solves the certified worst regions' points on the target and on the
/// host (f64 law): prints the cycles; the outputs agree within `tol` us
/// where the iterations agree.
pub(super) fn check_certified(
    avr: &mut AvrTester,
    dec: &mut FrameDecoder,
    scalar: &str,
    solver: &str,
    tol: f64,
) {
    let c = certification();
    let nx = generated::NX;
    let mut cases: Vec<Case> = Vec::new();
    for (name, r) in [
        ("cold worst iterations", &c.cold.worst),
        ("cold worst flops", &c.cold.worst_flops_region),
    ] {
        if let Some(r) = r {
            cases.push((name, None, r.theta.clone(), r.iterations));
        }
    }
    if let Some(w) = &c.warm {
        for (name, r) in [
            ("warm worst iterations", &w.worst),
            ("warm worst flops", &w.worst_flops_region),
        ] {
            if let Some(r) = r {
                cases.push((name, r.theta_prev.clone(), r.theta.clone(), r.iterations));
            }
        }
    }
    // The host reference of the build: warm-started with the warm cap (qp),
    // or cold every period with the cold cap (qp16, qp16-ldl).
    let (cap, warm_law) = super::qp_reference(solver);
    let mut stats = CycleStats::new();
    for (k, (name, prev, theta, certified)) in cases.iter().enumerate() {
        let th: [f32; generated::NP] = std::array::from_fn(|j| grid(theta[j]));
        let mut host = host_qp_law(cap, warm_law);
        let mut u = [0.0; 4];
        let warm = prev.is_some();
        if let Some(p) = prev {
            let pt: [f32; generated::NP] = std::array::from_fn(|j| grid(p[j]));
            solve(avr, dec, 2 * k as u16, pt, false);
            let pf: Vec<f64> = pt.iter().map(|&v| f64::from(v)).collect();
            host.control(&pf[..nx], &pf[nx..], &mut u).unwrap();
        }
        // The same case at the region's own point (not on the grid), on the
        // host: whether the rounding left the region.
        let exact_iterations = {
            let mut h = host_qp_law(cap, warm_law);
            let mut v = [0.0; 4];
            if let Some(p) = prev {
                h.control(&p[..nx], &p[nx..], &mut v).unwrap();
            }
            h.control(&theta[..nx], &theta[nx..], &mut v).unwrap();
            h.iterations()
        };
        let s = solve(avr, dec, 2 * k as u16 + 1, th, warm);
        let tf: Vec<f64> = th.iter().map(|&v| f64::from(v)).collect();
        host.control(&tf[..nx], &tf[nx..], &mut u).unwrap();
        let err =
            s.u.iter()
                .zip(&u)
                .map(|(a, b)| (f64::from(*a) - b).abs())
                .fold(0.0, f64::max);
        println!(
            "{solver} {scalar} at the certified {name} ({certified} iterations certified; {exact_iterations} by the host law at the region's point): {} iterations on the target, {} on the host, {} cycles, |u - host| {err:.2e} us",
            s.iterations,
            host.iterations(),
            s.cycles
        );
        if s.iterations == host.iterations() {
            assert!(err <= tol, "{name}: outputs differ by {err} us");
        }
        stats.add(s.cycles);
    }
    println!(
        "{solver} {scalar} at the certified worst cases: {} cycles",
        min_mean_max(&stats)
    );
    if std::env::var_os("KESTREL_HIL_REPORT").is_some() {
        println!(
            "QP-CHECK {{\"scalar\": \"{scalar}\", \"solver\": \"{solver}\", \"start\": \"certified-worst\", \"samples\": {}, \"cycles\": {{\"min\": {}, \"mean\": {:.1}, \"max\": {}}}, \"max_iterations\": {}}}",
            stats.count,
            stats.min,
            stats.mean().unwrap_or(0.0),
            stats.max,
            cap
        );
    }
}
