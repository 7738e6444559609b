#![doc = include_str!("../README.md")]
#![cfg_attr(not(feature = "std"), no_std)]
#![cfg_attr(target_arch = "avr", feature(asm_experimental_arch))]

// Assembly text (macros) for the AVR routines; first, so they are in scope below.
#[cfg(target_arch = "avr")]
#[macro_use]
mod avr_asm;
#[cfg(target_arch = "avr")]
pub mod bench_uart;
mod clamp;
pub mod control;
pub mod crc;
pub mod cycles;
pub mod explicit;
pub mod fgm16;
pub mod frame;
#[cfg(feature = "std")]
pub mod host;
pub mod interim;
pub mod kalman16;
pub mod law;
pub mod locate;
pub mod mac;
pub mod output;
pub mod progmem;
pub mod qp16;
mod shift;

pub use crc::crc16;
