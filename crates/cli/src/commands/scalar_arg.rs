//! `--scalar f32|q16|f64`: the number type of exported Rust tables, as
//! `kestrel empc export` and `kestrel fgm certify --export` take it.

use kestrel_core::formats::ExportScalar;

/// Number type of exported tables (kestrel-core's [`ExportScalar`]).
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum ScalarArg {
    /// 32-bit float.
    F32,
    /// Q15.16 saturating fixed point (`kestrel_core::Q16`).
    Q16,
    /// 64-bit float.
    F64,
}

impl ScalarArg {
    /// The flag's spelling (`f32`, `q16`, `f64`), as output JSON names it.
    pub fn name(self) -> &'static str {
        match self {
            ScalarArg::F32 => "f32",
            ScalarArg::Q16 => "q16",
            ScalarArg::F64 => "f64",
        }
    }
}

impl From<ScalarArg> for ExportScalar {
    fn from(s: ScalarArg) -> Self {
        match s {
            ScalarArg::F32 => ExportScalar::F32,
            ScalarArg::Q16 => ExportScalar::Q16,
            ScalarArg::F64 => ExportScalar::F64,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::ValueEnum;

    #[test]
    fn name_is_the_flag_spelling() {
        for s in ScalarArg::value_variants() {
            assert_eq!(s.to_possible_value().unwrap().get_name(), s.name());
        }
    }
}
