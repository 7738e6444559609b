//! Little-endian numbers of the binary log formats, decoded to `f64`.

/// A fixed-size little-endian number type (Crazyflie `struct` codes, ULog
/// field types).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Number {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    I64,
    U64,
    F16,
    F32,
    F64,
    Bool,
}

impl Number {
    /// Bytes of one value.
    pub(crate) fn size(self) -> usize {
        match self {
            Number::I8 | Number::U8 | Number::Bool => 1,
            Number::I16 | Number::U16 | Number::F16 => 2,
            Number::I32 | Number::U32 | Number::F32 => 4,
            Number::I64 | Number::U64 | Number::F64 => 8,
        }
    }

    /// Decodes `b` (its first `size()` bytes; missing bytes read as 0).
    pub(crate) fn decode(self, b: &[u8]) -> f64 {
        let mut a = [0u8; 8];
        for (d, s) in a.iter_mut().zip(b.iter().take(self.size())) {
            *d = *s;
        }
        let [b0, b1, b2, b3, ..] = a;
        match self {
            Number::I8 => f64::from(b0 as i8),
            Number::U8 => f64::from(b0),
            Number::Bool => f64::from(u8::from(b0 != 0)),
            Number::I16 => f64::from(i16::from_le_bytes([b0, b1])),
            Number::U16 => f64::from(u16::from_le_bytes([b0, b1])),
            Number::F16 => f16_to_f64(u16::from_le_bytes([b0, b1])),
            Number::I32 => f64::from(i32::from_le_bytes([b0, b1, b2, b3])),
            Number::U32 => f64::from(u32::from_le_bytes([b0, b1, b2, b3])),
            Number::F32 => f64::from(f32::from_le_bytes([b0, b1, b2, b3])),
            Number::I64 => i64::from_le_bytes(a) as f64,
            Number::U64 => u64::from_le_bytes(a) as f64,
            Number::F64 => f64::from_le_bytes(a),
        }
    }
}

/// IEEE half precision to `f64`.
fn f16_to_f64(h: u16) -> f64 {
    let sign = if h & 0x8000 != 0 { -1.0 } else { 1.0 };
    let exp = i32::from((h >> 10) & 0x1f);
    let frac = f64::from(h & 0x3ff);
    sign * match exp {
        0 => frac * 2f64.powi(-24),
        31 if frac == 0.0 => f64::INFINITY,
        31 => f64::NAN,
        e => (1.0 + frac / 1024.0) * 2f64.powi(e - 15),
    }
}

#[cfg(test)]
mod tests {
    use super::Number;

    #[test]
    fn every_type_decodes_its_little_endian_bytes() {
        assert_eq!(Number::I8.decode(&[0xff]), -1.0);
        assert_eq!(Number::U16.decode(&0xbeefu16.to_le_bytes()), 48879.0);
        assert_eq!(Number::I32.decode(&(-7i32).to_le_bytes()), -7.0);
        assert_eq!(Number::F32.decode(&1.5f32.to_le_bytes()), 1.5);
        assert_eq!(
            Number::U64.decode(&(1u64 << 40).to_le_bytes()),
            (1u64 << 40) as f64
        );
        assert_eq!(Number::F64.decode(&(-2.25f64).to_le_bytes()), -2.25);
        assert_eq!(Number::Bool.decode(&[7]), 1.0);
        // Half precision: 1.0, -2.0, the smallest subnormal, infinity.
        assert_eq!(Number::F16.decode(&0x3c00u16.to_le_bytes()), 1.0);
        assert_eq!(Number::F16.decode(&0xc000u16.to_le_bytes()), -2.0);
        assert_eq!(Number::F16.decode(&1u16.to_le_bytes()), 2f64.powi(-24));
        assert_eq!(Number::F16.decode(&0x7c00u16.to_le_bytes()), f64::INFINITY);
        // Bytes beyond the type are not read.
        assert_eq!(Number::U8.decode(&[3, 0xff, 0xff]), 3.0);
    }
}
