// Controller tables, placed in flash (`.text.kestrel_tables`, read with ELPM).
//
// The values come from `generated.rs`, written on the host by
// `kestrel codegen` (5-state 50 Hz model,
// stationary Kalman gains from kestrel-kalman, fast-gradient data of the
// thesis-sized problem from kestrel-mpc + kestrel-fgm; see that file's
// header). f32 builds store f32 values, fixed-point builds the Q16 raw bits
// folded for Q16 (solver box shrunk by Q16's rounding bound).

pub use crate::generated::*;

/// The controller table (little-endian f32).
#[cfg(not(any(feature = "fixed", feature = "fixed-mac")))]
#[unsafe(link_section = ".text.kestrel_tables")]
#[used]
pub static TABLE: [u8; 4 * N_VALUES] = kestrel_avr_rt::progmem::f32_bytes(VALUES_F32);

/// The controller table (little-endian Q15.16 raw bits).
#[cfg(any(feature = "fixed", feature = "fixed-mac"))]
#[unsafe(link_section = ".text.kestrel_tables")]
#[used]
pub static TABLE: [u8; 4 * N_VALUES] = kestrel_avr_rt::progmem::i32_bytes(VALUES_Q16);
