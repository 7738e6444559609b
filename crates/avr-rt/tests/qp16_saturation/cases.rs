//! The crafted cases of `tests/qp16_saturation.rs`: exact sums built term
//! by term to land on, one past or half a unit across each `i32` limit
//! after the rounding, at the shifts and term counts where the routines
//! take their different paths, and records that make every pass loop's
//! saturating difference overflow both ways.

use kestrel_avr_rt::qp16::probe::PassVar;

const MAX: i128 = i32::MAX as i128;
const MIN: i128 = i32::MIN as i128;

/// A saturating operation of the AVR assembly (one class set each).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Routine {
    /// `mac_round` (the rounded sum, 72-bit accumulator).
    Mac,
    /// `rows_round`, general rounding shift.
    Rows,
    /// `rows_round`, the shift-25 path.
    Rows25,
    /// `Row16::apply_all` (the 16-bit rows routine without accumulation).
    Apply,
    /// `Row16::add_all` (the rounded row added to `out`, one saturation).
    Add,
    /// The members' residuals `unc - bound`.
    Members,
    /// A lower bound's negated multiplier.
    Stars,
    /// The scan's point `unc - out`.
    ScanPoint,
    /// The scan's violation above `hi`.
    ScanAbove,
    /// The scan's violation below `lo`.
    ScanBelow,
}

/// Where an exact (rounded) value lies against `i32`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Class {
    /// Above `i32::MAX`: saturated up.
    SatPos,
    /// Below `i32::MIN`: saturated down.
    SatNeg,
    /// Exactly `i32::MAX` (not saturated).
    AtMax,
    /// Exactly `i32::MIN` (not saturated).
    AtMin,
    /// A tie rounded up to `i32::MAX + 1`: saturated.
    TieUp,
    /// A tie rounded up onto `i32::MIN`: not saturated.
    TieMin,
}

impl Class {
    /// The class of `x` (`tie`: the rounding was a tie), if any.
    pub fn of(x: i128, tie: bool) -> Option<Class> {
        Some(if tie && x == MAX + 1 {
            Class::TieUp
        } else if tie && x == MIN {
            Class::TieMin
        } else if x > MAX {
            Class::SatPos
        } else if x < MIN {
            Class::SatNeg
        } else if x == MAX {
            Class::AtMax
        } else if x == MIN {
            Class::AtMin
        } else {
            return None;
        })
    }
}

impl Routine {
    /// Every class each routine's arithmetic can produce (docs/avr-qp.md:
    /// why the others cannot).
    pub fn required() -> Vec<(Routine, Class)> {
        use Class::*;
        let all = [SatPos, SatNeg, AtMax, AtMin, TieUp, TieMin];
        let mut out = Vec::new();
        for r in [
            Routine::Mac,
            Routine::Rows,
            Routine::Rows25,
            Routine::Apply,
            Routine::Add,
        ] {
            out.extend(all.map(|c| (r, c)));
        }
        for r in [Routine::Members, Routine::ScanPoint] {
            out.extend([SatPos, SatNeg, AtMax, AtMin].map(|c| (r, c)));
        }
        for r in [Routine::Stars, Routine::ScanAbove, Routine::ScanBelow] {
            out.extend([SatPos, AtMax].map(|c| (r, c)));
        }
        out
    }
}

/// One call of the AVR program (`tests/qp16_saturation/avr`).
#[derive(Clone, Debug)]
pub enum Case {
    /// `mac_round` of `n` terms: `a` is `ab` then `at`, `b` is `bb` then `bt`.
    Mac {
        n: usize,
        ab: i32,
        at: Vec<i32>,
        bb: i32,
        bt: Vec<i32>,
        shift: u8,
    },
    /// `rows_round` of `db.len()` rows of `k` terms: `r` is `rb` then
    /// `rt`, row `i` is `db[i]` then its `rt.len()` entries of `dt`.
    Rows {
        k: usize,
        shift: u8,
        rb: i32,
        rt: Vec<i32>,
        db: Vec<i32>,
        dt: Vec<i32>,
    },
    /// `Row16` rows `(c, shift, start)` over `v`, applied and added to `acc`.
    Row16 {
        rows: Vec<(Vec<i16>, u8, u8)>,
        v: Vec<i32>,
        acc: Vec<i32>,
    },
    /// `probe::members`.
    Members(Vec<PassVar>),
    /// `probe::stars(var, out, limit)`.
    Stars(Vec<PassVar>, Vec<i32>, i32),
    /// `probe::scan(var, out, k, tol)`.
    Scan(Vec<PassVar>, Vec<i32>, usize, i32),
}

fn lit(v: i32) -> String {
    if v == i32::MIN {
        "i32::MIN".into()
    } else {
        v.to_string()
    }
}

fn lits(v: &[i32]) -> String {
    let s: Vec<String> = v.iter().map(|x| lit(*x)).collect();
    format!("[{}]", s.join(", "))
}

fn vars(v: &[PassVar]) -> String {
    let s: Vec<String> = v
        .iter()
        .map(|x| {
            format!(
                "var({}, {}, {}, {}, {}, {}, {})",
                lit(x.unc),
                lit(x.lo),
                lit(x.hi),
                lit(x.star),
                x.pos,
                x.code,
                lit(x.nu)
            )
        })
        .collect();
    format!("[{}]", s.join(", "))
}

impl Case {
    /// The AVR program (of three) that runs this case.
    pub fn group(&self) -> usize {
        match self {
            Case::Mac { .. } | Case::Rows { .. } => 0,
            Case::Row16 { .. } => 1,
            Case::Members(_) | Case::Stars(..) | Case::Scan(..) => 2,
        }
    }

    /// The generated call in the AVR program.
    pub fn call(&self, id: usize) -> String {
        match self {
            Case::Mac {
                n,
                ab,
                at,
                bb,
                bt,
                shift,
            } => format!(
                "mac(&Mac {{ id: {id}, n: {n}, ab: {}, at: &{}, bb: {}, bt: &{}, shift: {shift} }});",
                lit(*ab),
                lits(at),
                lit(*bb),
                lits(bt)
            ),
            Case::Rows {
                k,
                shift,
                rb,
                rt,
                db,
                dt,
            } => format!(
                "rows(&Rows {{ id: {id}, k: {k}, shift: {shift}, rb: {}, rt: &{}, db: &{}, dt: &{} }});",
                lit(*rb),
                lits(rt),
                lits(db),
                lits(dt)
            ),
            Case::Row16 { rows, v, acc } => {
                let r: Vec<String> = rows
                    .iter()
                    .map(|(c, s, st)| {
                        let c: Vec<String> = c
                            .iter()
                            .map(|x| {
                                if *x == i16::MIN {
                                    "i16::MIN".into()
                                } else {
                                    x.to_string()
                                }
                            })
                            .collect();
                        format!("Row16::new([{}], {s}, {st})", c.join(", "))
                    })
                    .collect();
                format!(
                    "row16({id}, &[{}], &{}, {});",
                    r.join(", "),
                    lits(v),
                    lits(acc)
                )
            }
            Case::Members(v) => format!("members({id}, {});", vars(v)),
            Case::Stars(v, out, limit) => {
                format!("stars({id}, {}, {}, {});", vars(v), lits(out), lit(*limit))
            }
            Case::Scan(v, out, k, tol) => {
                format!(
                    "scan({id}, {}, {}, {k}, {});",
                    vars(v),
                    lits(out),
                    lit(*tol)
                )
            }
        }
    }
}

/// `h` as `parts` values in `[-MAX, MAX]` (summing to `h`).
fn split(h: i128, parts: usize) -> Vec<i32> {
    let mut left = h;
    let out: Vec<i32> = (0..parts)
        .map(|_| {
            let p = left.clamp(-MAX, MAX);
            left -= p;
            p as i32
        })
        .collect();
    assert_eq!(left, 0, "{h} needs more than {parts} parts");
    out
}

/// `mac_round` of `n >= 3` terms whose exact sum is `x`: `n - 3` equal
/// bulk terms near `x / (n - 3)`, then `(MIN, -h1) (MIN, -h2) (l, 1)`.
fn mac_exact(x: i128, n: usize, shift: u8) -> Case {
    let m = n - 3;
    let (ab, bb) = if m == 0 {
        (0, 0)
    } else {
        let p = x / m as i128;
        (i32::MIN, (-p / (1i128 << 31)).clamp(MIN, MAX) as i32)
    };
    let y = x - m as i128 * (ab as i128 * bb as i128);
    let h = y >> 31;
    let l = (y - (h << 31)) as i32;
    let hs = split(h, 2);
    Case::Mac {
        n,
        ab,
        at: vec![i32::MIN, i32::MIN, l],
        bb,
        bt: vec![-hs[0], -hs[1], 1],
        shift,
    }
}

/// `rows_round` rows of `k >= 4` terms whose sums are `xs` modulo `2^64`:
/// `r` is `rb` then `(MIN, MIN, MIN, 1)`, row `i` is `db[i]` then the
/// tail that makes its sum.
fn rows_exact(k: usize, shift: u8, rb: i32, db: &[i32], xs: &[i128]) -> Case {
    let mut dt = Vec::new();
    for (d, x) in db.iter().zip(xs) {
        let bulk = (k - 4) as i128 * *d as i128 * rb as i128;
        let y = (x - bulk) as i64 as i128;
        let h = y >> 31;
        let l = (y - (h << 31)) as i32;
        dt.extend(split(h, 3).iter().map(|p| -p));
        dt.push(l);
    }
    Case::Rows {
        k,
        shift,
        rb,
        rt: vec![i32::MIN, i32::MIN, i32::MIN, 1],
        db: db.to_vec(),
        dt,
    }
}

/// The bulk of the 16-bit rows' vector: `v` is `[MIN; M16]` then `(MIN,
/// 2^16, 2, 1)`.
const M16: usize = 20;

/// One 16-bit row over that vector whose exact sum is `x`.
fn row16_exact(x: i128, shift: u8) -> (Vec<i16>, u8, u8) {
    let step = M16 as i128 * MIN;
    let cb = ((x as f64 / step as f64).round() as i128).clamp(-32768, 32767);
    let y = x - cb * step;
    let h = y >> 31;
    let l = y - (h << 31);
    assert!((-32767..=32768).contains(&h), "{x}: row too large");
    let mut c = vec![cb as i16; M16];
    c.extend([
        (-h) as i16,
        (l >> 16) as i16,
        ((l & 0xFFFF) >> 1) as i16,
        (l & 1) as i16,
    ]);
    (c, shift, 0)
}

fn row16_v() -> Vec<i32> {
    let mut v = vec![i32::MIN; M16];
    v.extend([i32::MIN, 1 << 16, 2, 1]);
    v
}

/// The values at, half a unit around and one past both limits after
/// `round(x / 2^s)`.
fn limits(s: u32) -> Vec<i128> {
    if s == 0 {
        return vec![MAX, MAX + 1, MIN, MIN - 1, MAX - 1, MIN + 1];
    }
    let half = 1i128 << (s - 1);
    vec![
        MAX << s,
        (MAX << s) + half - 1,
        (MAX << s) + half,
        (MAX + 1) << s,
        MIN << s,
        (MIN << s) - half,
        (MIN << s) - half - 1,
        (MIN - 1) << s,
    ]
}

/// A record: `var(unc, lo, hi, star, pos, code, nu)`.
fn var(unc: i32, lo: i32, hi: i32, star: i32, pos: u8, code: u8, nu: i32) -> PassVar {
    PassVar {
        unc,
        lo,
        hi,
        w: 0,
        star,
        pos,
        code,
        nu,
    }
}

fn mac_cases(out: &mut Vec<Case>) {
    let one = |a: i32, b: i32, shift: u8| Case::Mac {
        n: 1,
        ab: 0,
        at: vec![a],
        bb: 0,
        bt: vec![b],
        shift,
    };
    let (imax, imin) = (i32::MAX, i32::MIN);
    out.extend([
        one(imax, imax, 16),
        one(imin, imax, 16),
        one(imin, imin, 16),
        one(imin, imin, 46),
        one(imax, 1 << 16, 16),
        one(imin, 1 << 16, 16),
        one(imax, 1 << 16, 0), // shift clamped to 16
        one(imin, imin, 255),  // shift clamped to 46
        one(-1, 1 << 15, 16),  // -0.5 rounds up to 0
    ]);
    // At, around and past the limits: the byte moves and bit shifts of
    // every residue (shift - 1 = 15, 16, 22, 23, 24, 30, 31, 32, 37).
    for (s, n) in [
        (16, 3),
        (17, 4),
        (23, 3),
        (24, 5),
        (25, 3),
        (31, 7),
        (32, 8),
        (33, 12),
        (38, 255),
    ] {
        for x in limits(s) {
            out.push(mac_exact(x, n, s as u8));
        }
    }
    // The largest sums: 255 terms (the assembly's most), and 256 (the
    // wrapper's portable path).
    for (n, ab, bb, shift) in [
        (255, imin, imin, 16),
        (255, imin, imax, 16),
        (255, imin, imin, 38),
        (255, imin, imin, 46),
        (255, imax, imin, 46),
        (255, -1, -1, 16),
        (256, imin, imin, 38),
        (256, imin, imax, 38),
    ] {
        out.push(Case::Mac {
            n,
            ab,
            at: vec![],
            bb,
            bt: vec![],
            shift,
        });
    }
    // 128 terms of 2^62 at shift 38 is exactly 2^31: one past MAX.
    out.push(Case::Mac {
        n: 128,
        ab: imin,
        at: vec![],
        bb: imin,
        bt: vec![],
        shift: 38,
    });
}

fn rows_cases(out: &mut Vec<Case>) {
    let (imax, imin) = (i32::MAX, i32::MIN);
    // At, around and past the limits (modulo 2^64) with different bulks:
    // none (k = 4), 59 terms of 2^62 (a multiple of 2^64: the sum wraps
    // inside the row), of 1 (every byte product 0xFE01: the most carries),
    // of mixed bytes; k = 63 (the carry-counting routine's most) and 64
    // (the wrapper's portable path).
    let bulks: [(usize, i32, [i32; 8]); 6] = [
        (4, 0, [0; 8]),
        (63, imin, [imin; 8]),
        (63, -1, [-1; 8]),
        (
            63,
            0x00FF_00FF,
            [
                0xFF00_FF00u32 as i32,
                imax,
                imin,
                -1,
                0x0101_0101,
                0x7F80_7F80,
                -0x7F80_7F81,
                1,
            ],
        ),
        (64, imin, [imin; 8]),
        (63, imax, [imax, imin, -1, 1, imax, imin, -1, 1]),
    ];
    for (i, s) in [16u32, 17, 24, 25, 26, 31, 32, 25, 16, 40]
        .into_iter()
        .enumerate()
    {
        let (k, rb, db) = bulks[i % bulks.len()];
        let xs = limits(s);
        out.push(rows_exact(k, s as u8, rb, &db[..xs.len()], &xs));
    }
    // The rest of the shift-25 path and the other whole-byte counts.
    let extremes: Vec<i128> = [
        i64::MAX,
        i64::MIN,
        0,
        -1,
        1,
        1 << 40,
        -(1 << 40),
        -(1 << 62),
    ]
    .map(i128::from)
    .into();
    for (k, s) in [(63, 25), (5, 25), (64, 25), (63, 33), (63, 41), (63, 46)] {
        let xs = if s == 25 {
            limits(25)
        } else {
            extremes.clone()
        };
        out.push(rows_exact(k, s as u8, -1, &[-1; 8], &xs));
    }
    for s in [16u8, 25, 32, 46] {
        let xs: Vec<i128> = [i64::MAX, i64::MIN, i64::MAX - 1, i64::MIN + 1]
            .map(i128::from)
            .into();
        out.push(rows_exact(63, s, imin, &[imin; 4], &xs));
    }
    // One and two terms; no terms (zeros); shifts clamped to 16 and 46.
    out.extend([
        Case::Rows {
            k: 1,
            shift: 16,
            rb: 0,
            rt: vec![imin],
            db: vec![0; 4],
            dt: vec![imin, imax, 1 << 16, -(1 << 16)],
        },
        Case::Rows {
            k: 1,
            shift: 25,
            rb: 0,
            rt: vec![imin],
            db: vec![0; 4],
            dt: vec![imin, imax, 1 << 25, -(1 << 25)],
        },
        Case::Rows {
            k: 2,
            shift: 0,
            rb: 0,
            rt: vec![imax, 1 << 15],
            db: vec![0; 2],
            dt: vec![1 << 16, 1, 1 << 16, -1],
        },
        Case::Rows {
            k: 2,
            shift: 200,
            rb: 0,
            rt: vec![imin, imin],
            db: vec![0; 2],
            dt: vec![imin, imin, imin, imax],
        },
        Case::Rows {
            k: 0,
            shift: 16,
            rb: 0,
            rt: vec![],
            db: vec![5, 6, 7],
            dt: vec![],
        },
    ]);
}

fn row16_cases(out: &mut Vec<Case>) {
    let v = row16_v();
    // Rounded rows at, around and past the limits; acc 0.
    for s in [0u32, 1, 4, 5, 8, 9, 16, 17, 19] {
        let rows: Vec<_> = limits(s).iter().map(|x| row16_exact(*x, s as u8)).collect();
        let acc = vec![0; rows.len()];
        out.push(Case::Row16 {
            rows,
            v: v.clone(),
            acc,
        });
    }
    // Accumulated rows: a tie onto / across a limit, one past, exactly at.
    for s in [1u32, 16, 20, 48] {
        let h = 1i128 << (s - 1);
        let spec = [
            (h, i32::MAX),
            (-h, i32::MIN),
            (h << 1, i32::MAX),
            (-(h << 1), i32::MIN),
            (0, i32::MAX),
            (h - 1, i32::MAX),
            (-h - 1, i32::MIN),
            (1i128 << (s + 20).min(49), i32::MIN),
        ];
        out.push(Case::Row16 {
            rows: spec.iter().map(|(x, _)| row16_exact(*x, s as u8)).collect(),
            v: v.clone(),
            acc: spec.iter().map(|(_, a)| *a).collect(),
        });
    }
    // 31 terms (the routine's most) of the largest products, every
    // rounding path; shifts above 48 taken as 48; starts within, at and
    // beyond the row.
    let mut big = |v: Vec<i32>, c: i16| {
        let n = v.len();
        let rows: Vec<_> = [
            (0, 0),
            (5, 0),
            (7, 0),
            (8, 0),
            (19, 0),
            (20, 3),
            (60, 0),
            (0, n as u8),
            (4, 200),
        ]
        .iter()
        .map(|&(s, st)| (vec![c; n], s, st))
        .collect();
        let acc = [
            i32::MAX,
            i32::MIN,
            -1,
            1,
            i32::MIN,
            i32::MAX,
            0,
            i32::MAX,
            i32::MIN,
        ]
        .to_vec();
        out.push(Case::Row16 { rows, v, acc });
    };
    big(vec![i32::MIN; 31], i16::MIN);
    big(vec![i32::MIN; 31], i16::MAX);
    big(vec![i32::MAX; 31], i16::MIN);
    big(vec![i32::MIN; 32], i16::MIN); // the portable path on the AVR
    big(vec![i32::MAX; 32], i16::MAX);
    // The short (24-bit value) and full terms at their boundary.
    let v4 = vec![0x7F_FFFF, -0x80_0000, 0x80_0000, -0x80_0001];
    out.push(Case::Row16 {
        rows: vec![
            (vec![i16::MIN, i16::MIN, i16::MIN, i16::MAX], 0, 0),
            (vec![i16::MAX, i16::MAX, i16::MAX, i16::MIN], 0, 0),
            (vec![256, -256, 256, -256], 0, 0),
            (vec![-256, 256, -256, 256], 0, 0),
            (vec![1, 1, 1, 1], 1, 0),
            (vec![i16::MIN, i16::MIN, i16::MIN, i16::MIN], 3, 1),
        ],
        v: v4,
        acc: vec![i32::MAX, i32::MIN, i32::MAX, i32::MIN, 0, i32::MIN],
    });
    out.extend([
        Case::Row16 {
            rows: vec![
                (vec![2], 0, 0),
                (vec![-2], 0, 0),
                (vec![1], 0, 0),
                (vec![-1], 0, 0),
            ],
            v: vec![i32::MAX],
            acc: vec![0, 0, 1, -2],
        },
        Case::Row16 {
            rows: vec![
                (vec![1, 1], 0, 0),
                (vec![-1, -1], 0, 0),
                (vec![i16::MIN, 0], 15, 0),
            ],
            v: vec![i32::MAX, 1],
            acc: vec![-1, 0, i32::MIN],
        },
    ]);
}

fn pass_cases(out: &mut Vec<Case>) {
    let (imax, imin) = (i32::MAX, i32::MIN);
    out.extend([
        // Residuals: up, down, exactly at both limits (lower and upper
        // sides, equal-bound codes), inactive records skipped.
        Case::Members(vec![
            var(imax, -1, 5, 0, 1, 0, 0),
            var(imin, -5, 1, 0, 2, 1, 0),
            var(imax, imin, imax, 0, 0, 0, 0),
            var(imax, 0, 9, 0, 3, 0, 0),
            var(imin, -9, 0, 0, 4, 1, 0),
            var(imax - 1, -1, -1, 0, 5, 2, 0),
            var(imin + 1, 2, 2, 0, 6, 3, 0),
            var(-1, imax, imax, 0, 7, 0, 0),
        ]),
        Case::Members(vec![
            var(imin, imax, imax, 0, 0, 0, 0),
            var(imin, imax, imax, 0, 1, 0, 0),
            var(imax, imin, imin, 0, 2, 1, 0),
        ]),
        Case::Members(vec![var(imax, imin, imax, 0, 0, 0, 0)]),
    ]);
    // Multipliers: a lower bound's negation of MIN saturates, of MIN + 1
    // is exactly MAX; upper bounds are not negated; equal bounds never
    // candidates; limits at both ends.
    let stars_var = vec![
        var(0, 0, 1, 0, 1, 0, 0),
        var(0, 0, 1, 0, 2, 0, 0),
        var(0, 0, 1, 0, 3, 0, 0),
        var(0, 0, 1, 0, 4, 1, 0),
        var(0, 0, 1, 77, 0, 0, 0),
        var(0, 0, 0, 0, 5, 2, 0),
        var(0, 0, 0, 0, 6, 3, 0),
        var(0, 0, 1, 0, 7, 1, 0),
    ];
    let stars_out = vec![imin, imin + 1, 1, imin, imin, -5, 0, 0];
    for limit in [0, -1, imin, imax, imin + 1] {
        out.push(Case::Stars(stars_var.clone(), stars_out.clone(), limit));
    }
    out.push(Case::Stars(
        vec![var(0, 0, 1, 0, 1, 0, 0), var(0, 0, 1, 0, 2, 0, 0)],
        vec![imax, -imax],
        imax,
    ));
    // The point and the most violated bound: the point saturated up and
    // down, exactly at both limits; violations above and below saturated
    // and exactly MAX; ties keep the first; equal bounds.
    let scan_var = vec![
        var(imax, imin, -1, 0, 0, 0, 11),
        var(imin, imax, imax, 0, 0, 0, 12),
        var(0, 0, 7, 9, 1, 1, 13),
        var(imax - 3, imin, 0, 0, 0, 0, 14),
        var(imin + 2, -1, imax, 0, 0, 0, 15),
        var(0, -4, 7, -9, 2, 0, 16),
        var(100, 3, 3, 0, 0, 0, 17),
        var(5, 0, 10, 0, 0, 0, 18),
    ];
    let scan_out = vec![0, 0, -1, 1, -3, 2, 0, 0];
    for tol in [0, imax - 1, imax] {
        out.push(Case::Scan(scan_var.clone(), scan_out.clone(), 2, tol));
    }
    // The below-side saturated violation first, then the equal-bound one.
    let mut swapped = scan_var.clone();
    swapped.swap(0, 1);
    let mut out2 = scan_out.clone();
    out2.swap(2, 3);
    out.push(Case::Scan(swapped, out2, 2, 0));
    out.push(Case::Scan(
        vec![var(100, 3, 3, 0, 0, 0, 0), var(5, 0, 10, 0, 0, 0, 0)],
        vec![0, 0],
        0,
        0,
    ));
    out.push(Case::Scan(
        vec![
            var(imin, imax, imax, 0, 0, 0, 0),
            var(imin, 0, 0, 0, 1, 2, 0),
            var(imax, imin, imin, 0, 0, 0, 0),
        ],
        vec![0, imax, imin],
        1,
        0,
    ));
}

/// Every case, in the order the AVR program runs them.
pub fn cases() -> Vec<Case> {
    let mut out = Vec::new();
    mac_cases(&mut out);
    rows_cases(&mut out);
    row16_cases(&mut out);
    pass_cases(&mut out);
    out
}
