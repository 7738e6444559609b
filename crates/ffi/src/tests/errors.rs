//! Bad tables and bad calls give their codes: NULL pointers, wrong sizes,
//! wrong checksums and formats, states never initialised; the checksum
//! function is CRC-16/CCITT-FALSE.

use super::fixtures::{Owned, empc_tables, generated_empc as ge, ram};
use crate::*;
use core::mem::MaybeUninit;
use core::ptr::{null, null_mut};
use std::vec::Vec;

/// Table `field` of a design (values, kalman16, fgm16).
fn field_mut(d: &mut KestrelDesign, field: usize) -> &mut KestrelBytes {
    match field {
        0 => &mut d.values,
        1 => &mut d.kalman16,
        _ => &mut d.fgm16,
    }
}

/// Statuses of every init function for the design `d` (f32 ones first).
fn inits(d: *const KestrelDesign) -> [KestrelStatus; 6] {
    let mut k = MaybeUninit::<KestrelKalman16F32>::zeroed();
    let mut f = MaybeUninit::<KestrelFgm16F32>::zeroed();
    let mut fq = MaybeUninit::<KestrelFgm16Q16>::zeroed();
    let mut l = std::boxed::Box::new(MaybeUninit::<KestrelRateLoopF32>::zeroed());
    let mut lq = std::boxed::Box::new(MaybeUninit::<KestrelRateLoopQ16>::zeroed());
    let mut c = MaybeUninit::uninit();
    // SAFETY: valid pointers to live locals; `d` is NULL or a design.
    unsafe {
        assert_eq!(
            kestrel_loop_config_default(c.as_mut_ptr()),
            KestrelStatus::Ok
        );
        [
            kestrel_kalman16_init_f32(k.as_mut_ptr(), d),
            kestrel_fgm16_init_f32(f.as_mut_ptr(), d),
            kestrel_rate_loop_init_fgm_f32(l.as_mut_ptr(), d, c.as_ptr()),
            kestrel_fgm16_init_q16(fq.as_mut_ptr(), d),
            kestrel_rate_loop_init_fgm_q16(lq.as_mut_ptr(), d, c.as_ptr()),
            {
                let mut z = [0f32; 4];
                kestrel_fgm_solve_f32(d, [0f32; 9].as_ptr(), null(), z.as_mut_ptr())
            },
        ]
    }
}

#[test]
fn the_checksum_is_crc16_ccitt_false() {
    let s = b"123456789";
    let (a, b) = (ram(&s[..4]), ram(&s[4..]));
    let mut out = 0u16;
    // SAFETY: valid pointers.
    unsafe {
        assert_eq!(
            kestrel_checksum([a, b].as_ptr(), 2, &mut out),
            KestrelStatus::Ok
        );
        assert_eq!(out, 0x29B1);
        assert_eq!(kestrel_checksum(null(), 0, &mut out), KestrelStatus::Ok);
        assert_eq!(out, 0xFFFF);
        assert_eq!(
            kestrel_checksum(null(), 1, &mut out),
            KestrelStatus::NullPointer
        );
        assert_eq!(
            kestrel_checksum([a].as_ptr(), 1, null_mut()),
            KestrelStatus::NullPointer
        );
        let none = KestrelBytes {
            data: null(),
            flash: 0,
            len: 4,
        };
        assert_eq!(
            kestrel_checksum([none].as_ptr(), 1, &mut out),
            KestrelStatus::NullPointer
        );
        // The design's checksum, recomputed from C's side.
        let o = Owned::new(KESTREL_FORMAT_F32);
        let d = o.design();
        let tail = [
            d.values_format,
            d.fgm_warm,
            d.fgm_iterations as u8,
            (d.fgm_iterations >> 8) as u8,
        ];
        let parts = [d.values, d.kalman16, d.fgm16, ram(&tail)];
        assert_eq!(
            kestrel_checksum(parts.as_ptr(), 4, &mut out),
            KestrelStatus::Ok
        );
        assert_eq!(out, d.checksum);
    }
}

#[test]
fn good_design_initialises_everything() {
    let f = Owned::new(KESTREL_FORMAT_F32);
    let q = Owned::new(KESTREL_FORMAT_Q16);
    let s = inits(&f.design());
    assert_eq!(s[..3], [KestrelStatus::Ok; 3]);
    // f32 values to the Q15.16 functions: the format.
    assert_eq!(s[3..5], [KestrelStatus::BadFormat; 2]);
    assert_eq!(s[5], KestrelStatus::Ok);
    let s = inits(&q.design());
    assert_eq!(
        s[0],
        KestrelStatus::Ok,
        "the filter does not read the values"
    );
    assert_eq!(s[1..3], [KestrelStatus::BadFormat; 2]);
    assert_eq!(s[3..5], [KestrelStatus::Ok; 2]);
    assert_eq!(s[5], KestrelStatus::BadFormat);
}

#[test]
fn null_pointers_give_null_pointer() {
    assert_eq!(inits(null()), [KestrelStatus::NullPointer; 6]);
    let o = Owned::new(KESTREL_FORMAT_F32);
    let d = o.design();
    for field in 0..3 {
        let mut bad = d;
        let b = field_mut(&mut bad, field);
        b.data = null();
        // A flash address means nothing off the AVR.
        b.flash = 0x1_0000;
        assert_eq!(
            inits(&bad),
            [KestrelStatus::NullPointer; 6],
            "table {field}"
        );
    }
    let mut c = MaybeUninit::uninit();
    let mut x = [0f32; 5];
    // SAFETY: NULL or valid pointers.
    unsafe {
        assert_eq!(
            kestrel_loop_config_default(null_mut()),
            KestrelStatus::NullPointer
        );
        assert_eq!(
            kestrel_loop_config_default(c.as_mut_ptr()),
            KestrelStatus::Ok
        );
        assert_eq!(
            kestrel_kalman16_init_f32(null_mut(), &d),
            KestrelStatus::NullPointer
        );
        assert_eq!(
            kestrel_rate_loop_init_fgm_f32(null_mut(), &d, c.as_ptr()),
            KestrelStatus::NullPointer
        );
        let mut l = std::boxed::Box::new(MaybeUninit::<KestrelRateLoopF32>::zeroed());
        assert_eq!(
            kestrel_rate_loop_init_fgm_f32(l.as_mut_ptr(), &d, null()),
            KestrelStatus::NullPointer
        );
        assert_eq!(
            kestrel_rate_loop_init_fgm_f32(l.as_mut_ptr(), &d, c.as_ptr()),
            KestrelStatus::Ok
        );
        let mut out = KestrelRateOutput::default();
        let input = KestrelRateInput {
            gyro: [0.0; 3],
            reference: [0.0; 3],
            throttle: 1200.0,
            fresh: 1,
        };
        assert_eq!(
            kestrel_rate_loop_step_f32(l.as_mut_ptr(), null(), null(), &mut out),
            KestrelStatus::NullPointer
        );
        assert_eq!(
            kestrel_rate_loop_step_f32(l.as_mut_ptr(), &input, null(), null_mut()),
            KestrelStatus::NullPointer
        );
        assert_eq!(
            kestrel_rate_loop_step_f32(null_mut(), &input, null(), &mut out),
            KestrelStatus::NullPointer
        );
        assert_eq!(
            kestrel_rate_loop_step_f32(l.as_mut_ptr(), &input, null(), &mut out),
            KestrelStatus::Ok
        );
        let mut k = MaybeUninit::<KestrelKalman16F32>::zeroed();
        assert_eq!(
            kestrel_kalman16_init_f32(k.as_mut_ptr(), &d),
            KestrelStatus::Ok
        );
        assert_eq!(
            kestrel_kalman16_measure_f32(k.as_mut_ptr(), null(), x.as_mut_ptr()),
            KestrelStatus::NullPointer
        );
        // The estimate is an optional output.
        assert_eq!(
            kestrel_kalman16_measure_f32(k.as_mut_ptr(), [0f32; 3].as_ptr(), null_mut()),
            KestrelStatus::Ok
        );
        assert_eq!(
            kestrel_kalman16_predict_f32(k.as_mut_ptr(), null(), x.as_mut_ptr()),
            KestrelStatus::NullPointer
        );
        let mut f = MaybeUninit::<KestrelFgm16F32>::zeroed();
        assert_eq!(
            kestrel_fgm16_init_f32(f.as_mut_ptr(), &d),
            KestrelStatus::Ok
        );
        assert_eq!(
            kestrel_fgm16_solve_f32(f.as_mut_ptr(), null(), null_mut(), null_mut()),
            KestrelStatus::NullPointer
        );
        assert_eq!(
            kestrel_fgm_solve_f32(&d, [0f32; 9].as_ptr(), null(), null_mut()),
            KestrelStatus::NullPointer
        );
        let mut e = MaybeUninit::<KestrelEmpc16F32>::zeroed();
        assert_eq!(
            kestrel_empc16_init_f32(e.as_mut_ptr(), null()),
            KestrelStatus::NullPointer
        );
        let t = KestrelEmpc16Tables {
            chunks: null(),
            ..empc_tables(&[ram(&ge::EMPC16)], &[&ge::EMPC16], ge::EMPC16_LAYOUT, 0)
        };
        assert_eq!(
            kestrel_empc16_init_f32(e.as_mut_ptr(), &t),
            KestrelStatus::NullPointer
        );
    }
}

#[test]
fn wrong_sizes_give_bad_size() {
    let o = Owned::new(KESTREL_FORMAT_F32);
    for field in 0..3 {
        for delta in [-1i32, 1, -4] {
            let mut bad = o.design();
            let b = field_mut(&mut bad, field);
            b.len = (b.len as i32 + delta) as u32;
            // (The length is checked before a byte is read.)
            let want = [KestrelStatus::BadSize; 6];
            assert_eq!(inits(&bad), want, "table {field}, {delta:+} bytes");
        }
    }
    // The explicit law: a table one byte short, a layout with other counts,
    // more parameters or fewer outputs than the C ABI serves.
    let narrow = [ram(&ge::EMPC16)];
    let short = [ram(&ge::EMPC16[..ge::EMPC16.len() - 1])];
    let check = |t: &KestrelEmpc16Tables| {
        let mut e = MaybeUninit::<KestrelEmpc16F32>::zeroed();
        // SAFETY: valid pointers.
        unsafe { kestrel_empc16_init_f32(e.as_mut_ptr(), t) }
    };
    let good = empc_tables(&narrow, &[&ge::EMPC16], ge::EMPC16_LAYOUT, 0);
    assert_eq!(check(&good), KestrelStatus::Ok);
    let t = empc_tables(
        &short,
        &[&ge::EMPC16[..ge::EMPC16.len() - 1]],
        ge::EMPC16_LAYOUT,
        0,
    );
    assert_eq!(check(&t), KestrelStatus::BadSize);
    for edit in 0..3 {
        let mut l = ge::EMPC16_LAYOUT;
        match edit {
            0 => l.n_nodes -= 1,
            1 => l.n_params = 10,
            _ => l.n_outputs = 3,
        }
        let t = empc_tables(&narrow, &[&ge::EMPC16], l, 0);
        assert_eq!(check(&t), KestrelStatus::BadSize, "layout edit {edit}");
    }
    // Chunks of the wrong lengths, none, or a chunk size beyond 24 bits.
    let halves = [ram(&ge::EMPC16[..4000]), ram(&ge::EMPC16[4000..])];
    let t = empc_tables(&halves, &[&ge::EMPC16], ge::EMPC16_LAYOUT, 12);
    assert_eq!(check(&t), KestrelStatus::BadSize);
    let t = KestrelEmpc16Tables {
        n_chunks: 0,
        ..good
    };
    assert_eq!(check(&t), KestrelStatus::BadSize);
    let t = KestrelEmpc16Tables {
        chunks: halves.as_ptr(),
        n_chunks: 2,
        chunk_bits: 24,
        ..good
    };
    assert_eq!(check(&t), KestrelStatus::BadSize);
    // Correct chunks of 4096 bytes read as one table.
    let four = [ram(&ge::EMPC16[..4096]), ram(&ge::EMPC16[4096..])];
    let t = empc_tables(&four, &[&ge::EMPC16], ge::EMPC16_LAYOUT, 12);
    assert_eq!(check(&t), KestrelStatus::Ok);
}

#[test]
fn wrong_checksums_and_tables_give_their_codes() {
    let o = Owned::new(KESTREL_FORMAT_F32);
    let d = o.design();
    let mut bad = d;
    bad.checksum ^= 1;
    assert_eq!(inits(&bad), [KestrelStatus::BadChecksum; 6]);
    // A byte changed in each table, or a field of the design.
    for field in 0..3 {
        let mut copy: [Vec<u8>; 3] = [o.values.clone(), o.kalman16.clone(), o.fgm16.clone()];
        copy[field][7] ^= 0x10;
        let mut bad = d;
        bad.values = ram(&copy[0]);
        bad.kalman16 = ram(&copy[1]);
        bad.fgm16 = ram(&copy[2]);
        assert_eq!(
            inits(&bad),
            [KestrelStatus::BadChecksum; 6],
            "table {field}"
        );
    }
    for edit in 0..2 {
        let mut bad = d;
        if edit == 0 {
            bad.fgm_iterations += 1
        } else {
            bad.fgm_warm ^= 1
        }
        assert_eq!(inits(&bad), [KestrelStatus::BadChecksum; 6], "field {edit}");
    }
    // An unknown format is refused before the checksum.
    let mut bad = d;
    bad.values_format = 7;
    assert_eq!(inits(&bad), [KestrelStatus::BadFormat; 6]);
    // The explicit law's checksum covers its bytes and its layout.
    let narrow = [ram(&ge::EMPC16)];
    let mut t = empc_tables(&narrow, &[&ge::EMPC16], ge::EMPC16_LAYOUT, 0);
    let mut e = MaybeUninit::<KestrelEmpc16F32>::zeroed();
    t.checksum ^= 0x8000;
    // SAFETY: valid pointers.
    assert_eq!(
        unsafe { kestrel_empc16_init_f32(e.as_mut_ptr(), &t) },
        KestrelStatus::BadChecksum
    );
    let mut copy = ge::EMPC16.to_vec();
    copy[100] ^= 1;
    let one = [ram(&copy)];
    let t = KestrelEmpc16Tables {
        chunks: one.as_ptr(),
        ..empc_tables(&narrow, &[&ge::EMPC16], ge::EMPC16_LAYOUT, 0)
    };
    assert_eq!(
        unsafe { kestrel_empc16_init_f32(e.as_mut_ptr(), &t) },
        KestrelStatus::BadChecksum
    );
    // A row shift above 40 in a (re-checksummed) Kalman table.
    let mut k = o.kalman16.clone();
    k[10] = 41; // the first C row's shift
    let tail = [
        d.values_format,
        d.fgm_warm,
        d.fgm_iterations as u8,
        (d.fgm_iterations >> 8) as u8,
    ];
    let mut bad = d;
    bad.kalman16 = ram(&k);
    bad.checksum = kestrel_avr_rt::crc16(&[&o.values[..], &k, &o.fgm16, &tail].concat());
    assert_eq!(
        inits(&bad)[..3],
        [
            KestrelStatus::InvalidTable,
            KestrelStatus::Ok,
            KestrelStatus::InvalidTable
        ],
        "the fast gradient law alone does not read the Kalman rows"
    );
}

#[test]
fn states_never_initialised_are_refused() {
    let mut x = [0f32; 5];
    let mut out = KestrelRateOutput {
        pwm: [1; 4],
        ..Default::default()
    };
    let input = KestrelRateInput {
        gyro: [0.0; 3],
        reference: [0.0; 3],
        throttle: 1200.0,
        fresh: 1,
    };
    let mut k = MaybeUninit::<KestrelKalman16F32>::zeroed();
    let mut f = MaybeUninit::<KestrelFgm16F32>::zeroed();
    let mut e = MaybeUninit::<KestrelEmpc16F32>::zeroed();
    let mut l = std::boxed::Box::new(MaybeUninit::<KestrelRateLoopF32>::zeroed());
    // SAFETY: valid pointers to zeroed states.
    unsafe {
        assert_eq!(
            kestrel_kalman16_measure_f32(k.as_mut_ptr(), [0f32; 3].as_ptr(), x.as_mut_ptr()),
            KestrelStatus::NotInitialised
        );
        assert_eq!(
            kestrel_fgm16_solve_f32(f.as_mut_ptr(), [0f32; 9].as_ptr(), null_mut(), null_mut()),
            KestrelStatus::NotInitialised
        );
        assert_eq!(
            kestrel_empc16_eval_f32(
                e.as_mut_ptr(),
                x.as_ptr(),
                [0f32; 4].as_ptr(),
                [0f32; 4].as_mut_ptr(),
                null_mut()
            ),
            KestrelStatus::NotInitialised
        );
        assert_eq!(
            kestrel_rate_loop_step_f32(l.as_mut_ptr(), &input, null(), &mut out),
            KestrelStatus::NotInitialised
        );
        assert_eq!(out.pwm, [1; 4], "the output is not touched");
        // A failed init leaves the state uninitialised, even over a good one.
        let o = Owned::new(KESTREL_FORMAT_F32);
        let d = o.design();
        let mut c = MaybeUninit::uninit();
        assert_eq!(
            kestrel_loop_config_default(c.as_mut_ptr()),
            KestrelStatus::Ok
        );
        assert_eq!(
            kestrel_rate_loop_init_fgm_f32(l.as_mut_ptr(), &d, c.as_ptr()),
            KestrelStatus::Ok
        );
        let mut bad = d;
        bad.checksum ^= 1;
        assert_eq!(
            kestrel_rate_loop_init_fgm_f32(l.as_mut_ptr(), &bad, c.as_ptr()),
            KestrelStatus::BadChecksum
        );
        assert_eq!(
            kestrel_rate_loop_step_f32(l.as_mut_ptr(), &input, null(), &mut out),
            KestrelStatus::NotInitialised
        );
        // Crossed limits and a gyro check without a full scale.
        let mut cfg = c.assume_init();
        cfg.esc_min = 2100;
        assert_eq!(
            kestrel_rate_loop_init_fgm_f32(l.as_mut_ptr(), &d, &cfg),
            KestrelStatus::InvalidTable
        );
        let mut cfg = c.assume_init();
        cfg.gyro_full_scale = f32::NAN;
        assert_eq!(
            kestrel_rate_loop_init_fgm_f32(l.as_mut_ptr(), &d, &cfg),
            KestrelStatus::InvalidTable
        );
        cfg.gyro_stuck_periods = 0; // no check: the full scale is not read
        assert_eq!(
            kestrel_rate_loop_init_fgm_f32(l.as_mut_ptr(), &d, &cfg),
            KestrelStatus::Ok
        );
    }
}

#[test]
fn non_finite_and_infeasible_inputs_give_their_codes() {
    let o = Owned::new(KESTREL_FORMAT_F32);
    let d = o.design();
    let mut f = MaybeUninit::<KestrelFgm16F32>::zeroed();
    let mut k = MaybeUninit::<KestrelKalman16F32>::zeroed();
    let mut z = [7f32; 4];
    let mut t = [0f32; 9];
    t[8] = 1200.0;
    // SAFETY: valid pointers.
    unsafe {
        assert_eq!(
            kestrel_fgm16_init_f32(f.as_mut_ptr(), &d),
            KestrelStatus::Ok
        );
        assert_eq!(
            kestrel_kalman16_init_f32(k.as_mut_ptr(), &d),
            KestrelStatus::Ok
        );
        assert_eq!(
            kestrel_fgm16_solve_f32(f.as_mut_ptr(), t.as_ptr(), z.as_mut_ptr(), null_mut()),
            KestrelStatus::Ok
        );
        t[0] = f32::NAN;
        let before = z;
        assert_eq!(
            kestrel_fgm16_solve_f32(f.as_mut_ptr(), t.as_ptr(), z.as_mut_ptr(), null_mut()),
            KestrelStatus::NonFinite
        );
        assert_eq!(z, before, "outputs untouched on an error");
        assert_eq!(
            kestrel_fgm_solve_f32(&d, t.as_ptr(), null(), z.as_mut_ptr()),
            KestrelStatus::NonFinite
        );
        assert_eq!(
            kestrel_kalman16_measure_f32(
                k.as_mut_ptr(),
                [f32::INFINITY, 0.0, 0.0].as_ptr(),
                null_mut()
            ),
            KestrelStatus::NonFinite
        );
    }
    // A design whose box is empty: lo0 above hi0 for the first variable.
    let mut v = o.values.clone();
    let at = |i: usize| 4 * i..4 * i + 4;
    v[at(super::fixtures::generated::FGM_LO0)].copy_from_slice(&1.0e4f32.to_le_bytes());
    let tail = [
        d.values_format,
        d.fgm_warm,
        d.fgm_iterations as u8,
        (d.fgm_iterations >> 8) as u8,
    ];
    let mut bad = d;
    bad.values = ram(&v);
    bad.checksum = kestrel_avr_rt::crc16(&[&v[..], &o.kalman16, &o.fgm16, &tail].concat());
    t[0] = 0.0;
    // SAFETY: valid pointers.
    unsafe {
        assert_eq!(
            kestrel_fgm16_init_f32(f.as_mut_ptr(), &bad),
            KestrelStatus::Ok
        );
        assert_eq!(
            kestrel_fgm16_solve_f32(f.as_mut_ptr(), t.as_ptr(), z.as_mut_ptr(), null_mut()),
            KestrelStatus::Infeasible
        );
        assert_eq!(
            kestrel_fgm_solve_f32(&bad, t.as_ptr(), null(), z.as_mut_ptr()),
            KestrelStatus::Infeasible
        );
    }
}

#[test]
fn every_runtime_error_has_its_code() {
    use kestrel_core::Error;
    let all = [
        (
            Error::DimensionMismatch {
                expected: 1,
                found: 2,
            },
            KestrelStatus::BadSize,
        ),
        (Error::NonFinite, KestrelStatus::NonFinite),
        (Error::Singular, KestrelStatus::Singular),
        (
            Error::NotPositiveDefinite,
            KestrelStatus::NotPositiveDefinite,
        ),
        (Error::Infeasible, KestrelStatus::Infeasible),
        (Error::Unbounded, KestrelStatus::Unbounded),
        (Error::NotConverged, KestrelStatus::NotConverged),
        (Error::InvalidArgument("x"), KestrelStatus::InvalidTable),
        (Error::OutOfRange, KestrelStatus::OutOfRange),
    ];
    for (e, s) in all {
        assert_eq!(status_of(e), s);
    }
    assert_eq!(kestrel_abi_version(), KESTREL_ABI_VERSION);
}
