//! The fuzz entry points of every kestrel reader and `no_std` table
//! validator: one `fn(&[u8]) -> Outcome` per fuzz target.
//!
//! Shared by the cargo-fuzz targets (`fuzz/fuzz_targets/*.rs`, through the
//! `kestrel-fuzz` library) and the stable-toolchain regression test
//! `tests/tests/fuzz_regressions.rs` (through `#[path]`), so both feed the
//! same bytes to the same calls. An entry point returns `Ok` or the clean
//! error the reader gave as text; a panic, an abort or a hang is a finding.
//! Where a read succeeds, the entry point goes on with what a caller does
//! next (write it back and read it again, evaluate the tables, run the
//! filter or law a few periods) and asserts what must then hold.

use kestrel_avr_rt::explicit::tree16::{Empc16Law, Tree16, Tree16Layout};
use kestrel_avr_rt::explicit::{EmpcLaw, FlashTree, TreeLayout};
use kestrel_avr_rt::fgm16::Fgm16Law;
use kestrel_avr_rt::frame::{Bench, Boot, Command, FrameDecoder, MAX_FRAME, Reply, SeqTracker};
use kestrel_avr_rt::kalman16::{Kalman16, Kalman16Tables, Row16};
use kestrel_avr_rt::mac::Q16Mac;
use kestrel_avr_rt::output::RtScalar;
use kestrel_core::formats::{MpqpProblem, SsModel, json, matrix_from_text, parameter_rows};
use kestrel_core::{ControlLaw, Matrix, StateEstimator};
use kestrel_empc::export::{self, ExportScalar};
use kestrel_empc::{AnyTables, CompactTables, evaluate_with};
use kestrel_fgm::FgmTables;
use kestrel_kalman::KalmanDesign;
use kestrel_sysid::{CsvColumns, IoData, TimeUnit};

/// What an entry point gives back: `Ok`, or the reader's error as text.
pub type Outcome = Result<(), String>;

/// An entry point: the bytes of one input to its outcome.
pub type Entry = fn(&[u8]) -> Outcome;

/// Every fuzz target by name (the name of its `fuzz_targets/*.rs` file
/// and of its folder under `fuzz/regressions/`).
pub const TARGETS: [(&str, Entry); 13] = [
    ("ss", ss),
    ("mpqp", mpqp),
    ("kalman", kalman),
    ("empc_solution", empc_solution),
    ("csv_log", csv_log),
    ("frame", frame),
    ("tree16", tree16),
    ("flash_tree", flash_tree),
    ("fgm16", fgm16),
    ("kalman16", kalman16),
    ("thetas", thetas),
    ("matrix_file", matrix_file),
    ("logs", logs),
];

fn text(data: &[u8]) -> Result<&str, String> {
    std::str::from_utf8(data).map_err(|e| format!("not UTF-8: {e}"))
}

/// Reads `data` with `read`; what it reads is written with `write` and
/// must read back unchanged.
fn round_trip<T: PartialEq + core::fmt::Debug, E: core::fmt::Display>(
    data: &[u8],
    read: fn(&str) -> Result<T, E>,
    write: fn(&T) -> String,
) -> Outcome {
    let x = read(text(data)?).map_err(|e| e.to_string())?;
    match read(&write(&x)) {
        Ok(back) => assert_eq!(back, x, "what is written reads back unchanged"),
        Err(e) => panic!("what is written reads back, not: {e}"),
    }
    Ok(())
}

/// `kestrel.ss.v1`: read; a model read is written and read back unchanged.
pub fn ss(data: &[u8]) -> Outcome {
    round_trip(data, SsModel::from_json_str, SsModel::to_json_string)
}

/// `kestrel.mpqp.v1`: read; a problem read is written and read back unchanged.
pub fn mpqp(data: &[u8]) -> Outcome {
    round_trip(
        data,
        MpqpProblem::from_json_str,
        MpqpProblem::to_json_string,
    )
}

/// `kestrel.kalman.v1`: read; a design read is written and read back unchanged.
pub fn kalman(data: &[u8]) -> Outcome {
    round_trip(
        data,
        KalmanDesign::from_json_str,
        KalmanDesign::to_json_string,
    )
}

/// A parameter for tables of `p` parameters: the box's midpoint moved by
/// the byte `b` (inside, on and outside the box).
fn theta_at(lb: &[f64], ub: &[f64], b: u8) -> Vec<f64> {
    let s = (f64::from(b) - 128.0) / 64.0;
    lb.iter()
        .zip(ub)
        .map(|(l, u)| 0.5 * (l + u) + s * (u - l))
        .collect()
}

/// Solution files (`kestrel.empc.v1`) and their tables: which formats the
/// file holds, the single tree and the compact tables read with every
/// index checked; tables read are evaluated (inside, on and outside the
/// box) and written as Rust source (which may refuse them cleanly).
pub fn empc_solution(data: &[u8]) -> Outcome {
    let text = text(data)?;
    let formats = export::table_formats(text).map_err(|e| e.to_string())?;
    let probe = data.iter().copied().take(4);
    let mut read_any = false;
    match export::read_tables::<AnyTables>(text) {
        Ok(t) => {
            read_any = true;
            let (lb, ub, k) = match &t {
                AnyTables::Narrow(t) => (&t.theta_lb, &t.theta_ub, t.n_outputs),
                AnyTables::Wide(t) => (&t.theta_lb, &t.theta_ub, t.n_outputs),
            };
            let mut z = vec![0.0; k];
            for b in probe.clone() {
                let _ = t.evaluate_f64(&theta_at(lb, ub, b), &mut z);
            }
            // Q16 refuses numbers beyond its range (a clean error).
            let _ = match &t {
                AnyTables::Narrow(t) => export::rust_source(t, ExportScalar::Q16),
                AnyTables::Wide(t) => export::rust_source(t, ExportScalar::F32),
            };
        }
        Err(e) if formats.is_empty() => return Err(e.to_string()),
        Err(_) => {}
    }
    match export::read_tables::<CompactTables<f64>>(text) {
        Ok(t) => {
            let forest = t.tables();
            let mut z = vec![0.0; t.n_outputs];
            let mut scratch = vec![0.0; t.n_params];
            for b in probe {
                let theta = theta_at(&t.theta_lb, &t.theta_ub, b);
                let _ = evaluate_with(&forest, &theta, &mut scratch, &mut z);
            }
            let _ = export::rust_source(&t, ExportScalar::F64);
            Ok(())
        }
        Err(e) if !read_any => Err(e.to_string()),
        Err(_) => Ok(()),
    }
}

/// CSV logs: the first byte picks the columns' settings (time unit, a
/// given sample time), the rest is the file; inputs `u`, outputs `y`,
/// time `t`, experiments `experiment`.
pub fn csv_log(data: &[u8]) -> Outcome {
    let Some((&mode, file)) = data.split_first() else {
        return Err("empty input".into());
    };
    let mut columns = CsvColumns::new(&["u"], &["y"]);
    if mode & 1 != 0 {
        columns.time_unit = TimeUnit::Milliseconds;
    }
    if mode & 2 != 0 {
        columns.ts = Some(0.02);
    }
    if mode & 4 != 0 {
        columns.inputs = vec!["u".into(), "v".into()];
    }
    let d = IoData::from_csv_reader(file, &columns, "fuzz.csv").map_err(|e| e.to_string())?;
    assert!(
        d.ts().is_finite() && d.ts() > 0.0,
        "a read log has a sample time"
    );
    assert!(d.n_samples() > 0, "a read log has samples");
    Ok(())
}

/// Parameter rows (`fgm solve --thetas`, `empc eval --thetas`): the first
/// byte picks the number of parameters p (0 to 7), the rest is the CSV
/// text; rows read have p finite numbers each and, written back one per
/// line, read back unchanged.
pub fn thetas(data: &[u8]) -> Outcome {
    let Some((&mode, file)) = data.split_first() else {
        return Err("empty input".into());
    };
    let p = usize::from(mode % 8);
    let rows = parameter_rows(text(file)?, p).map_err(|e| e.to_string())?;
    let mut back = String::new();
    for row in &rows {
        assert_eq!(row.len(), p, "a row read has p numbers");
        assert!(row.iter().all(|v| v.is_finite()), "a row read is finite");
        let fields: Vec<String> = row.iter().map(|v| format!("{v:?}")).collect();
        back.push_str(&fields.join(","));
        back.push('\n');
    }
    match parameter_rows(&back, p) {
        Ok(again) => assert_eq!(again, rows, "rows written read back unchanged"),
        Err(e) => panic!("rows written read back, not: {e}"),
    }
    Ok(())
}

/// JSON matrix files (`kestrel mpc --q1/--q2/--terminal`, `kestrel kalman
/// --q/--r/--g/--cross`): the first byte picks the expected rows and
/// columns (bits 0-2 and 3-5: 0 to 6, or 7 for any) and the key (bit 6:
/// `Q` or `G`), the rest is the file; a matrix read has the expected shape
/// and finite entries, and reads back unchanged written as a bare array
/// and as an object holding the key.
pub fn matrix_file(data: &[u8]) -> Outcome {
    let Some((&mode, file)) = data.split_first() else {
        return Err("empty input".into());
    };
    let dim = |bits: u8| (bits != 7).then_some(usize::from(bits));
    let (rows, cols) = (dim(mode & 7), dim((mode >> 3) & 7));
    let key = if mode & 64 != 0 { "G" } else { "Q" };
    let m = matrix_from_text(text(file)?, key, rows, cols).map_err(|e| e.to_string())?;
    assert!(rows.is_none_or(|r| m.nrows() == r), "rows as expected");
    assert!(cols.is_none_or(|c| m.ncols() == c), "columns as expected");
    assert!(m.iter().all(|v| v.is_finite()), "a matrix read is finite");
    let array = json::matrix_to_value(&m);
    let mut obj = json::Object::new();
    obj.insert(key.into(), array.clone());
    for back in [array.to_string(), json::to_pretty_string(&obj)] {
        match matrix_from_text(&back, key, rows, cols) {
            Ok(again) => assert_eq!(
                (again.shape(), again.as_slice()),
                (m.shape(), m.as_slice()),
                "a matrix written reads back unchanged: {back}"
            ),
            Err(e) => panic!("a matrix written reads back, not: {e}: {back}"),
        }
    }
    Ok(())
}

/// `kestrel-logs`: the bytes as a flight log (format from the magic
/// bytes), read salvaging and strict, each imported at 50 Hz over the
/// whole log; the outcome is the strict reading's.
pub fn logs(data: &[u8]) -> Outcome {
    let settings = kestrel_logs::ImportSettings {
        segment: kestrel_logs::SegmentChoice::All,
        ..Default::default()
    };
    let mut outcome = Ok(());
    for salvage in [true, false] {
        outcome = kestrel_logs::read_bytes(data, &kestrel_logs::ReadOptions { salvage })
            .and_then(|logs| kestrel_logs::import(&logs, &settings))
            .map(|_| ())
            .map_err(|e| e.to_string());
    }
    outcome
}

/// The firmware's frame decoder fed the bytes one at a time: every frame
/// decoded is re-encoded and decodes to itself; its payload is read as
/// each message type and its sequence number tracked.
pub fn frame(data: &[u8]) -> Outcome {
    let mut dec = FrameDecoder::new();
    let mut seq = SeqTracker::new();
    let mut frames = 0usize;
    for &b in data {
        let Some(Ok(f)) = dec.push(b) else { continue };
        frames += 1;
        let _ = seq.accept(f.seq);
        let _ = (Command::from_frame(&f), Reply::from_frame(&f));
        let _ = (Boot::from_frame(&f), Bench::from_frame(&f));
        let mut buf = [0u8; MAX_FRAME];
        let n = f.encode(&mut buf).expect("a decoded frame encodes");
        let mut again = FrameDecoder::new();
        let back: Vec<_> = buf[..n].iter().filter_map(|&b| again.push(b)).collect();
        assert_eq!(back, [Ok(f)], "a re-encoded frame decodes to itself");
    }
    let _ = dec.reset();
    if frames == 0 {
        return Err("no frame".into());
    }
    Ok(())
}

/// Little-endian fields read off the front of the fuzz input (zeros once
/// it runs out).
struct Bytes<'a>(&'a [u8]);

impl<'a> Bytes<'a> {
    fn take<const N: usize>(&mut self) -> [u8; N] {
        let mut out = [0u8; N];
        let n = N.min(self.0.len());
        out[..n].copy_from_slice(&self.0[..n]);
        self.0 = &self.0[n..];
        out
    }
    fn u8(&mut self) -> u8 {
        self.take::<1>()[0]
    }
    fn u16(&mut self) -> u16 {
        u16::from_le_bytes(self.take())
    }
    fn i16(&mut self) -> i16 {
        i16::from_le_bytes(self.take())
    }
    fn i32(&mut self) -> i32 {
        i32::from_le_bytes(self.take())
    }
    fn f32(&mut self) -> f32 {
        f32::from_le_bytes(self.take())
    }
    /// A count: 16 bits, or 32 bits with `wide`.
    fn count(&mut self, wide: bool) -> usize {
        if wide {
            u32::from_le_bytes(self.take()) as usize
        } else {
            usize::from(self.u16())
        }
    }
    fn f32s<const K: usize>(&mut self) -> [f32; K] {
        core::array::from_fn(|_| self.f32())
    }
    fn rows<const K: usize, const C: usize>(&mut self) -> [[f32; C]; K] {
        core::array::from_fn(|_| self.f32s())
    }
    fn row<const C: usize>(&mut self) -> Row16<C> {
        let c = core::array::from_fn(|_| self.i16());
        Row16::new(c, self.u8(), self.u8())
    }
    fn rest(&mut self) -> &'a [u8] {
        core::mem::take(&mut self.0)
    }
}

/// The table bytes after a layout: the rest of the input as it is
/// (`exact`), or cut or padded with zeros to the layout's size (at most
/// 64 KiB) so that the validator's checks past the length are reached.
fn table_bytes(rest: &[u8], exact: bool, want: usize) -> Vec<u8> {
    let mut t = rest.to_vec();
    if !exact {
        t.resize(want.min(1 << 16), 0);
    }
    t
}

/// Runs a control law four periods on states, references and inputs from `b`.
fn run_law<L: ControlLaw>(law: &mut L, b: &mut Bytes<'_>, num: impl Fn(f32) -> L::Scalar) {
    for _ in 0..4 {
        let x: Vec<_> = (0..law.nx()).map(|_| num(b.f32())).collect();
        let r: Vec<_> = (0..law.nr()).map(|_| num(b.f32())).collect();
        let mut u: Vec<_> = (0..law.nu()).map(|_| num(b.f32())).collect();
        let _ = law.control(&x, &r, &mut u);
    }
}

/// Parameters `P`, outputs `NU` and cached rows `R` of the `tree16` and
/// `flash_tree` targets' laws.
const P: usize = 3;
const NU: usize = 2;
const R: usize = 16;

/// The firmware's 16-bit explicit MPC table: a [`Tree16Layout`] from the
/// front of the input (flags, then counts), the table bytes after it;
/// `Tree16::new` and `Empc16Law::new` validate them, and a law they accept
/// runs four periods in f32 or Q15.16.
pub fn tree16(data: &[u8]) -> Outcome {
    let mut b = Bytes(data);
    let flags = b.u8();
    let wide = flags & 1 != 0;
    let big = flags & 2 != 0;
    let mut layout = Tree16Layout {
        n_params: P,
        n_outputs: NU,
        n_nodes: b.count(big),
        n_laws: b.count(big),
        n_rows: b.count(big),
        root: b.u16(),
        scale: b.u8(),
        wide,
    };
    if flags & 4 != 0 {
        layout.n_params = b.count(big);
        layout.n_outputs = b.count(big);
    }
    let nx = usize::from(b.u8() % 4);
    let fit = layout.checked_offsets().map_or(0, |o| o[4] as usize);
    let table = table_bytes(b.rest(), flags & 8 != 0, fit);
    let tree = Tree16::new(&table[..], layout).map_err(|e| e.to_string())?;
    let mut probe = Bytes(data.get(1..).unwrap_or_default());
    if flags & 16 != 0 {
        let mut law = Empc16Law::<Q16Mac, _, P, NU, R>::new(tree, nx).map_err(|e| e.to_string())?;
        run_law(&mut law, &mut probe, Q16Mac::from_f32_fast);
    } else {
        let mut law = Empc16Law::<f32, _, P, NU, R>::new(tree, nx).map_err(|e| e.to_string())?;
        run_law(&mut law, &mut probe, |v| v);
    }
    Ok(())
}

/// The generic flash table of the explicit MPC ([`FlashTree`], read by
/// kestrel-empc's `no_std` evaluation): a [`TreeLayout`] from the front of
/// the input, the table after it; `FlashTree::new` and `EmpcLaw::new`
/// validate them, and a law they accept runs four periods.
pub fn flash_tree(data: &[u8]) -> Outcome {
    let mut b = Bytes(data);
    let flags = b.u8();
    let big = flags & 2 != 0;
    let mut layout = TreeLayout {
        n_params: P,
        n_outputs: NU,
        root: b.u16(),
        n_nodes: b.count(big),
        n_laws: b.count(big),
        n_rows: b.count(big),
        n_hull: b.count(big),
    };
    if flags & 4 != 0 {
        layout.n_params = b.count(big);
        layout.n_outputs = b.count(big);
    }
    let nx = usize::from(b.u8() % 4);
    let fit = layout.checked_bytes(4).unwrap_or(0);
    let table = table_bytes(b.rest(), flags & 8 != 0, fit);
    let tree = FlashTree::<_, f32>::new(&table[..], layout).map_err(|e| e.to_string())?;
    let mut law = EmpcLaw::<f32, _, P, NU>::new(tree, nx).map_err(|e| e.to_string())?;
    run_law(
        &mut law,
        &mut Bytes(data.get(1..).unwrap_or_default()),
        |v| v,
    );
    Ok(())
}

/// Variables `N`, momentum entries `T` of the `fgm16` target's law.
const N: usize = 2;
const T: usize = 2;

/// The fixed-point fast gradient law: kestrel-fgm's tables (f32), the
/// rows of `M`, the momentum table, `nx`, warm start and iteration count
/// from the input; `Fgm16Law::new` validates them, and a law it accepts
/// runs four periods.
pub fn fgm16(data: &[u8]) -> Outcome {
    let mut b = Bytes(data);
    let setup = FgmTables::<f32, N, P, T> {
        m: Matrix::from_rows(b.rows()),
        k_theta: Matrix::from_rows(b.rows()),
        k0: b.f32s(),
        lo_theta: Matrix::from_rows(b.rows()),
        lo0: b.f32s(),
        hi_theta: Matrix::from_rows(b.rows()),
        hi0: b.f32s(),
        d: b.f32s(),
        d_inv: b.f32s(),
        betas: b.f32s(),
        iterations: usize::from(b.u16()),
        warm_iterations: usize::from(b.u16()),
        shift: usize::from(b.u8()),
    };
    let m16 = core::array::from_fn(|_| b.row::<N>());
    let betas = core::array::from_fn(|_| b.i16());
    let (nx, warm, iterations) = (usize::from(b.u8()), b.u8() & 1 != 0, b.u16() & 0x3ff);
    let mut law = Fgm16Law::<f32, N, P, T, 1>::new(setup, m16, betas, nx, warm, iterations)
        .map_err(|e| e.to_string())?;
    run_law(&mut law, &mut b, |v| v);
    Ok(())
}

/// The 16-bit stationary Kalman filter: its tables (rows of `C`, `y0`,
/// rows of `M`, `A - I`, `B`) from the input; `Kalman16Tables::check`
/// validates them, and a filter it accepts runs four steps (in f32 or
/// Q15.16) on measurements and inputs from the rest of the input.
pub fn kalman16(data: &[u8]) -> Outcome {
    let mut b = Bytes(data);
    let q16 = b.u8() & 1 != 0;
    let tables = Kalman16Tables::<3, 2, 2> {
        c: core::array::from_fn(|_| b.row()),
        y0: core::array::from_fn(|_| b.i32()),
        m: core::array::from_fn(|_| b.row()),
        a: core::array::from_fn(|_| b.row()),
        b: core::array::from_fn(|_| b.row()),
    };
    tables.check().map_err(|e| e.to_string())?;
    let _ = tables.multiply_adds();
    if q16 {
        run_filter(
            &mut Kalman16::<Q16Mac, 3, 2, 2>::new(tables),
            &mut b,
            Q16Mac::from_f32_fast,
        );
    } else {
        run_filter(&mut Kalman16::<f32, 3, 2, 2>::new(tables), &mut b, |v| v);
    }
    Ok(())
}

/// Runs a filter four steps on measurements and inputs from `b`, then resets it.
fn run_filter<F: StateEstimator>(f: &mut F, b: &mut Bytes<'_>, num: impl Fn(f32) -> F::Scalar) {
    for _ in 0..4 {
        let y: Vec<_> = (0..f.ny()).map(|_| num(b.f32())).collect();
        let _ = f.measurement_update(&y);
        let u: Vec<_> = (0..f.nu()).map(|_| num(b.f32())).collect();
        let _ = f.time_update(&u);
        let _ = f.estimate();
    }
    let x0: Vec<_> = (0..f.nx()).map(|_| num(b.f32())).collect();
    let _ = f.reset(&x0);
}
