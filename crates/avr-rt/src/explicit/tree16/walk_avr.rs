//! The AVR assembly of the 16-bit explicit law's period (`tree16::Empc16Law`): one routine,
//! `kestrel_empc16_eval`, that quantises `theta` from Q15.16, walks the
//! tree in flash and evaluates the leaf's clamped outputs, with the row
//! value cache in RAM. It does exactly what the law's Rust path does (the
//! host's reference), in the same integer arithmetic:
//!
//! - quantisation: `q_j = clamp(round(bits_j / 2^s_j), lb_j, ub_j)`
//!   (a byte move per 8 bits of the shift, then one 4-cycle pass per bit),
//!   read in place from two pointers (the state, then the references);
//!   with `f32` parameters (`Ctx::f32_theta`) each value's Q15.16 `bits_j`
//!   comes first from its exponent and mantissa in registers (the
//!   mantissa rounded half away from zero by `134 - exponent` bits, or
//!   shifted left, or saturated: `RtScalar::to_q16` for `f32`, bit for
//!   bit), with no Q15.16 copy in RAM;
//! - a row: the `i32` constant plus `sum c_k theta_k` over the stored
//!   columns, each term a 16 x 16-bit product from four hardware
//!   multiplies (`MUL`, `MULSU` twice, `MULS`) added into a 32-bit
//!   accumulator held in registers, gains read with `ELPM Z+` (32 cycles
//!   per term): with nine parameters (the tricopter) rows from column 0
//!   unrolled with `theta_k` read by `LDD Y+q`, one-term rows (column 8)
//!   the last of those terms, constant rows none; other rows in a loop
//!   with `LD X+`. The value comes back in r16:r19 and into the cache
//!   (the period stamp, then the value; a cached row costs a stamp
//!   compare and four loads);
//! - a node: its 5 bytes by `ELPM Z+`, its rows through the cache, a
//!   signed 32-bit compare;
//! - the leaf: per output its law row clamped to its bound rows, rounded
//!   to Q15.16 (`out_shift`; one bit inline);
//! - indices: `Empc16Law::new` checks every row, law and
//!   node index of the table once (a right child after its node, so every
//!   walk ends) and refuses a corrupted table with
//!   [`kestrel_core::Error::OutOfRange`]; the routine reads them unchecked.
//!
//! The routine is one `asm!` block (the context pointer in Z, the status
//! in r24, every other register declared clobbered; Y, the frame
//! pointer, saved and restored by the block, r1 cleared) and keeps its
//! context struct in Y, `theta` right after it (the law's scratch). It
//! leaves RAMPZ set (only `ELPM` reads it).

/// The routine's context (offsets are the assembly's `Y+q`).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub(crate) struct Ctx {
    /// 0: flash address (24-bit, little-endian, then a pad byte) of node 0.
    pub nodes: [u8; 4],
    /// 4: of row 0.
    pub rows: [u8; 4],
    /// 8: of the laws' row indices.
    pub laws: [u8; 4],
    /// 12: of the output bounds' row indices.
    pub bounds: [u8; 4],
    /// 16: RAM address of the cache (`theta`, `P` `i16`, directly before it).
    pub cache: u16,
    /// 18: RAM address of the Q15.16 `theta` (`P` `i32`); 0: `theta` is
    /// already quantised in the scratch.
    pub q16: u16,
    /// 20: RAM address of the parameters' 5 bytes each (shift, `lb`, `ub`).
    pub params: u16,
    /// 22: RAM address of the outputs (`NU` `i32`).
    pub out: u16,
    /// 24: the root code.
    pub root: u16,
    /// 26: nodes.
    pub n_nodes: u16,
    /// 28: rows.
    pub n_rows: u8,
    /// 29: laws.
    pub n_laws: u8,
    /// 30: parameters.
    pub np: u8,
    /// 31: outputs.
    pub nu: u8,
    /// 32: bytes per row.
    pub rb: u8,
    /// 33: the period stamp of valid cache entries.
    pub period: u8,
    /// 34: out: nodes visited.
    pub steps: u16,
    /// 36: out: non-zero if `theta` was outside the box.
    pub outside: u8,
    /// 37: out: the leaf's law.
    pub law: u8,
    /// 38: non-zero: the values at `q16` and `q16b` are `f32` bit
    /// patterns, converted to Q15.16 by the routine exactly as
    /// `RtScalar::to_q16` for `f32` does (then quantised as Q15.16 values
    /// are); a non-finite one ends the routine with status 2.
    pub f32_theta: u8,
    /// 39: outputs are rounded and shifted right by this many bits
    /// (0: the raw row values).
    pub out_shift: u8,
    /// 40: RAM address of the Q15.16 `theta` values after the first `nx`.
    pub q16b: u16,
    /// 42: how many values `q16` holds (then `q16b`).
    pub nx: u8,
}

/// The leaf's bound row r24 into r20:r23, the output's value kept in
/// r16:r19: read straight from the cache when this period's (the common
/// case: the walk's nodes compared it), else through the row routine
/// (the value saved on the stack around it).
#[rustfmt::skip]
macro_rules! bound {
    () => {
        concat!(
            "ldi r20, 5\n",
            "mul r24, r20\n",
            "movw r26, r4\n",
            "add r26, r0\n",
            "adc r27, r1\n",
            "ld r20, X+\n",
            "cp r20, r3\n",
            "brne 7f\n",
            "ld r20, X+\n",
            "ld r21, X+\n",
            "ld r22, X+\n",
            "ld r23, X+\n",
            "rjmp 6f\n",
            "7:\n",
            "push r16\n",
            "push r17\n",
            "push r18\n",
            "push r19\n",
            "rcall .Lke_row\n",
            "movw r20, r16\n",
            "movw r22, r18\n",
            "pop r19\n",
            "pop r18\n",
            "pop r17\n",
            "pop r16\n",
            "6:",
        )
    };
}

/// One term of a row, `acc += c_k theta_k` (22 instructions, 32 cycles):
/// the gain `c` by `ELPM Z+` into r20:r21, `theta_k` into r22:r23 by the
/// two given loads (`LD X+` in the row loop, `LDD Y+q` in the unrolled
/// row), the 16 x 16-bit signed product from four hardware multiplies
/// added into the 32-bit accumulator r16:r19 (r2 is zero).
#[rustfmt::skip]
macro_rules! term {
    ($lo:expr, $hi:expr) => {
        concat!(
            "elpm r20, Z+\n",
            "elpm r21, Z+\n",
            $lo, "\n",
            $hi, "\n",
            "mul r20, r22\n", // c_lo t_lo, byte 0
            "add r16, r0\n",
            "adc r17, r1\n",
            "adc r18, r2\n",
            "adc r19, r2\n",
            "mulsu r21, r22\n", // c_hi t_lo, byte 1 (C: sign)
            "sbc r19, r2\n",
            "add r17, r0\n",
            "adc r18, r1\n",
            "adc r19, r2\n",
            "mulsu r23, r20\n", // t_hi c_lo, byte 1
            "sbc r19, r2\n",
            "add r17, r0\n",
            "adc r18, r1\n",
            "adc r19, r2\n",
            "muls r21, r23\n", // c_hi t_hi, byte 2
            "add r18, r0\n",
            "adc r19, r1",
        )
    };
}

/// Term `k` of the unrolled nine-term row: `theta_k` at `Y + 43 + 2k`.
macro_rules! term_y {
    ($lo:literal, $hi:literal) => {
        term!(concat!("ldd r22, Y+", $lo), concat!("ldd r23, Y+", $hi))
    };
}

/// Byte offset of `theta` in the scratch block the routine's Y points at
/// (directly after the [`Ctx`]).
pub(crate) const THETA_AT: usize = 43;
const _: () = assert!(core::mem::size_of::<Ctx>() == THETA_AT);

/// See the module docs. Returns 0, or 2 for a non-finite `f32` value
/// (the table's indices were checked by the law's `new`).
///
/// Registers during the walk: r2 zero, r3 the period stamp, r4:r5 the
/// cache, r6 the bytes per row, r7:r9 the rows' flash address (r8 low, r9 high, r7
/// the top byte), r10 node row `b`, r11 node left child, r12:r13 node
/// right child, r14:r15 the child
/// code, r25 nodes visited (low byte; the high byte in the context), the T
/// flag set for nine parameters (the unrolled rows). In the leaf r12:r14
/// and r10, r11, r15 are the 24-bit flash addresses of the next law row
/// index and bound row indices, r25 the outputs left.
///
/// # Safety
/// `ctx` must be the start of the law's scratch block (the [`Ctx`], then
/// `theta`, then the cache) and describe the law's parameters, outputs
/// and a table in flash as [`Ctx`] documents, a table whose indices the
/// law's `new` checked (the routine follows them unchecked).
#[inline(never)]
#[allow(named_asm_labels)] // one copy: the function is never inlined
pub(crate) unsafe fn kestrel_empc16_eval(ctx: *mut Ctx) -> u8 {
    let status: u8;
    // SAFETY: the caller's contract; Y (the frame pointer, which cannot
    // be an operand) is saved and restored around the routine, r1 is
    // cleared, r0 is scratch; every other register it writes is declared.
    unsafe {
        core::arch::asm!(
        "push r28",
        "push r29",
        "movw r28, r30",          // Y = ctx (theta at Y+43)
        "clr r2",                 // zero
        "ldd r3, Y+33",           // period
        "ldd r4, Y+16",           // cache base
        "ldd r5, Y+17",
        "clt",                    // T: nine parameters
        "ldd r24, Y+30",
        "cpi r24, 9",
        "brne 9f",
        "set",
        "9:",
        // ---- quantisation (skipped when q16 == 0): X bits (q16, after nx
        // values q16b), Z parameters, r8:r9 where theta_j goes, r11 values
        // left from the current pointer, r6 from q16b after it, r7 outside
        "clr r7",
        "ldd r26, Y+18",
        "ldd r27, Y+19",
        "mov r24, r26",
        "or r24, r27",
        "brne 9f",
        "rjmp .Lke_walk",
        "9:",
        "ldd r30, Y+20",
        "ldd r31, Y+21",
        "ldd r6, Y+30",
        "ldd r11, Y+42",          // r11 values from q16, then r6 from q16b
        "sub r6, r11",
        "ldd r15, Y+38",          // f32 values
        "movw r8, r28",
        "ldi r24, 43",
        "add r8, r24",
        "adc r9, r2",
        "tst r11",
        "brne .Lke_q",
        "rjmp .Lke_qb",
        ".Lke_q:",
        "ld r16, X+",
        "ld r17, X+",
        "ld r18, X+",
        "ld r19, X+",
        "sbrc r15, 0",            // f32 bits: converted first (.Lke_fcv)
        "rjmp .Lke_fcv",
        ".Lke_qp:",
        "ld r20, Z+",             // s
        "ld r22, Z+",             // lb
        "ld r23, Z+",
        "ld r24, Z+",             // ub
        "ld r25, Z+",
        "tst r20",
        "breq .Lke_qclamp",
        round_shift!(".Lke_", "r20", "q"),
        ".Lke_qclamp:",
        "mov r21, r23",           // lb's sign byte
        "lsl r21",
        "sbc r21, r21",
        "cp r16, r22",
        "cpc r17, r23",
        "cpc r18, r21",
        "cpc r19, r21",
        "brge .Lke_qub",
        "movw r16, r22",          // v < lb: lb
        "inc r7",
        "rjmp .Lke_qstore",
        ".Lke_qub:",
        "mov r21, r25",           // ub's sign byte
        "lsl r21",
        "sbc r21, r21",
        "cp r24, r16",
        "cpc r25, r17",
        "cpc r21, r18",
        "cpc r21, r19",
        "brge .Lke_qstore",
        "movw r16, r24",          // v > ub: ub
        "inc r7",
        ".Lke_qstore:",
        "movw r12, r30",
        "movw r30, r8",
        "st Z+, r16",
        "st Z+, r17",
        "movw r8, r30",
        "movw r30, r12",
        "dec r11",
        "breq 9f",
        "rjmp .Lke_q",
        "9:",
        ".Lke_qb:",               // on from q16b (r6 values)
        "tst r6",
        "breq .Lke_walk",
        "mov r11, r6",
        "clr r6",
        "ldd r26, Y+40",
        "ldd r27, Y+41",
        "rjmp .Lke_q",
        // ---- the walk
        ".Lke_walk:",
        "std Y+36, r7",
        "ldd r6, Y+32",           // bytes per row
        "ldd r8, Y+4",            // rows
        "ldd r9, Y+5",
        "ldd r7, Y+6",
        "ldd r14, Y+24",          // code
        "ldd r15, Y+25",
        "clr r25",                // nodes visited
        "std Y+35, r2",
        ".Lke_node:",
        "sbrc r15, 7",
        "rjmp .Lke_leaf",
        "movw r30, r14",          // Z = nodes + 5 code (new(): 5 n_nodes < 64 KiB)
        "lsl r30",
        "rol r31",
        "lsl r30",
        "rol r31",
        "add r30, r14",
        "adc r31, r15",
        "ldd r16, Y+0",
        "ldd r17, Y+1",
        "ldd r18, Y+2",
        "add r30, r16",
        "adc r31, r17",
        "adc r18, r2",
        "out 0x3B, r18",
        "elpm r24, Z+",           // a
        "elpm r10, Z+",           // b
        "elpm r11, Z+",           // left
        "elpm r12, Z+",           // right
        "elpm r13, Z+",
        "inc r25",                // nodes visited
        "brne 9f",
        "ldd r16, Y+35",
        "inc r16",
        "std Y+35, r16",
        "9:",
        "rcall .Lke_row",         // a
        "mov r24, r10",
        "cpi r24, 0xFF",
        "breq .Lke_zero",
        "push r16",
        "push r17",
        "push r18",
        "push r19",
        "rcall .Lke_row",         // b
        "pop r23",                // a
        "pop r22",
        "pop r21",
        "pop r20",
        "cp r16, r20",            // b - a
        "cpc r17, r21",
        "cpc r18, r22",
        "cpc r19, r23",
        "brlt .Lke_right",        // b < a
        "rjmp .Lke_left",
        ".Lke_zero:",
        "cp r2, r16",             // 0 - a
        "cpc r2, r17",
        "cpc r2, r18",
        "cpc r2, r19",
        "brlt .Lke_right",
        ".Lke_left:",             // a <= b
        "mov r24, r11",
        "cpi r24, 0xFF",
        "brne .Lke_lleaf",
        "sec",                    // the next node
        "adc r14, r2",
        "adc r15, r2",
        "rjmp .Lke_node",
        ".Lke_lleaf:",
        "mov r14, r24",
        "ldi r24, 0x80",
        "mov r15, r24",
        "rjmp .Lke_leaf",
        ".Lke_right:",
        "movw r14, r12",
        "rjmp .Lke_node",
        // ---- the leaf: law r14 (checked); per output (r25 left) its law
        // row clamped to its bound rows, rounded, into *out
        ".Lke_leaf:",
        "std Y+34, r25",
        "std Y+37, r14",
        "ldd r25, Y+31",          // outputs left
        "tst r25",
        "brne 9f",
        "rjmp .Lke_done",
        "9:",
        "mul r14, r25",           // r12:r13:r14 = the law's row indices
        "ldd r12, Y+8",
        "ldd r13, Y+9",
        "ldd r14, Y+10",
        "add r12, r0",
        "adc r13, r1",
        "adc r14, r2",
        "ldd r10, Y+12",          // r10:r11:r15 = the output bounds' rows
        "ldd r11, Y+13",
        "ldd r15, Y+14",
        ".Lke_out:",
        "movw r30, r12",          // v = the law's row (ELPM Z+ carries into RAMPZ)
        "out 0x3B, r14",
        "elpm r24, Z+",
        "movw r12, r30",
        "in r14, 0x3B",
        "rcall .Lke_row",
        "movw r30, r10",          // lo
        "out 0x3B, r15",
        "elpm r24, Z+",
        "movw r10, r30",
        "in r15, 0x3B",
        "cpi r24, 0xFF",
        "breq .Lke_ohi",
        bound!(),
        "cp r16, r20",            // v - lo
        "cpc r17, r21",
        "cpc r18, r22",
        "cpc r19, r23",
        "brge .Lke_ohi",          // v < lo: lo
        "movw r16, r20",
        "movw r18, r22",
        ".Lke_ohi:",
        "movw r30, r10",          // hi
        "out 0x3B, r15",
        "elpm r24, Z+",
        "movw r10, r30",
        "in r15, 0x3B",
        "cpi r24, 0xFF",
        "breq .Lke_ost",
        bound!(),
        "cp r20, r16",            // hi - v
        "cpc r21, r17",
        "cpc r22, r18",
        "cpc r23, r19",
        "brge .Lke_ost",          // hi < v: hi
        "movw r16, r20",
        "movw r18, r22",
        ".Lke_ost:",
        "ldd r24, Y+39",          // v = round(v / 2^out_shift)
        "cpi r24, 1",
        "brne .Lke_osh",
        "asr r19",                // one bit (the tricopter's K = 17)
        "ror r18",
        "ror r17",
        "ror r16",
        "adc r16, r2",
        "adc r17, r2",
        "adc r18, r2",
        "adc r19, r2",
        "rjmp .Lke_st2",
        ".Lke_osh:",
        "tst r24",
        "breq .Lke_st2",
        round_shift!(".Lke_", "r24", "o"),
        ".Lke_st2:",
        "ldd r30, Y+22",
        "ldd r31, Y+23",
        "st Z+, r16",
        "st Z+, r17",
        "st Z+, r18",
        "st Z+, r19",
        "std Y+22, r30",
        "std Y+23, r31",
        "dec r25",
        "breq .Lke_done",
        "rjmp .Lke_out",
        ".Lke_done:",
        "clr r24",
        "clr r1",
        "pop r29",
        "pop r28",
        "rjmp .Lke_end",
        // f32 bits to Q15.16 (RtScalar::to_q16 for f32): e the exponent,
        // m the mantissa with its implicit bit, sign mask r10
        ".Lke_fcv:",
        f32_to_q16!(".Lke_", "f", "r10", "r20", ".Lke_nonfinite"),
        "rjmp .Lke_qp",
        ".Lke_nonfinite:",        // a non-finite f32 value: status 2
        "std Y+36, r2",
        "ldi r24, 2",
        "clr r1",
        "pop r29",
        "pop r28",
        "rjmp .Lke_end",
        // ---- row r24 (checked by the law's new): its value in r16:r19.
        // Clobbers r0, r1, r16-r24, X, Z, RAMPZ.
        ".Lke_row:",
        "ldi r16, 5",             // X = the cache entry
        "mul r24, r16",
        "movw r26, r4",
        "add r26, r0",
        "adc r27, r1",
        "ld r16, X+",
        "cp r16, r3",
        "brne .Lke_miss",
        "ld r16, X+",             // cached
        "ld r17, X+",
        "ld r18, X+",
        "ld r19, X+",
        "ret",
        ".Lke_rgen:",             // n = P - start terms from theta + start
        "ldd r24, Y+30",
        "sub r24, r20",
        "breq .Lke_rg0",
        "brcs .Lke_rg0",
        "push r26",
        "push r27",
        "movw r26, r28",
        "adiw r26, 43",
        "add r26, r20",
        "adc r27, r2",
        "add r26, r20",
        "adc r27, r2",
        ".Lke_term:",
        term!("ld r22, X+", "ld r23, X+"),
        "dec r24",
        "brne .Lke_term",
        "pop r27",
        "pop r26",
        ".Lke_rg0:",
        "rjmp .Lke_rst",
        ".Lke_miss:",             // X = the entry + 1
        "mul r24, r6",            // Z:RAMPZ = rows + r rb
        "movw r30, r0",
        "add r30, r8",
        "adc r31, r9",
        "mov r16, r7",
        "adc r16, r2",
        "out 0x3B, r16",
        "elpm r20, Z+",           // start
        "elpm r16, Z+",           // the constant
        "elpm r17, Z+",
        "elpm r18, Z+",
        "elpm r19, Z+",
        "brtc .Lke_rgen",         // nine parameters: unrolled from 0 or 8
        "tst r20",
        "breq .Lke_t0",
        "cpi r20, 8",
        "brne 9f",
        "rjmp .Lke_t8",
        "9:",
        "cpi r20, 9",
        "brne .Lke_rgen",
        "rjmp .Lke_rst",
        ".Lke_t0:",
        term_y!("43", "44"),
        term_y!("45", "46"),
        term_y!("47", "48"),
        term_y!("49", "50"),
        term_y!("51", "52"),
        term_y!("53", "54"),
        term_y!("55", "56"),
        term_y!("57", "58"),
        ".Lke_t8:",
        term_y!("59", "60"),
        ".Lke_rst:",
        "st -X, r3",              // the stamp, then the value
        "adiw r26, 1",
        "st X+, r16",
        "st X+, r17",
        "st X+, r18",
        "st X+, r19",
        "ret",
        ".Lke_end:",
        inout("Z") ctx => _,
        out("r24") status,
        out("r2") _, out("r3") _, out("r4") _, out("r5") _, out("r6") _, out("r7") _,
        out("r8") _, out("r9") _, out("r10") _, out("r11") _, out("r12") _, out("r13") _,
        out("r14") _, out("r15") _, out("r16") _, out("r17") _, out("r18") _, out("r19") _,
        out("r20") _, out("r21") _, out("r22") _, out("r23") _, out("r25") _, out("X") _,
        );
    }
    status
}
