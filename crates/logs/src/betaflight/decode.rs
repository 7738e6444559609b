//! The variable-byte encodings of Betaflight blackbox frames.

use super::defs::Encoding;

/// Why a read stopped: the data ended, or a value is malformed.
#[derive(Debug)]
pub(crate) enum Stop {
    /// The data ends inside the value at this offset.
    End,
    /// A variable-byte integer runs longer than 5 bytes.
    LongVarint(usize),
}

/// A reader over one log's bytes.
pub(crate) struct Reader<'a> {
    pub bytes: &'a [u8],
    pub pos: usize,
}

impl Reader<'_> {
    pub fn byte(&mut self) -> Result<u8, Stop> {
        let b = *self.bytes.get(self.pos).ok_or(Stop::End)?;
        self.pos += 1;
        Ok(b)
    }

    pub fn unsigned_vb(&mut self) -> Result<u32, Stop> {
        let start = self.pos;
        let mut v: u32 = 0;
        for shift in (0..35).step_by(7) {
            let b = self.byte()?;
            v |= u32::from(b & 0x7f).wrapping_shl(shift);
            if b & 0x80 == 0 {
                return Ok(v);
            }
        }
        Err(Stop::LongVarint(start))
    }

    pub fn signed_vb(&mut self) -> Result<i32, Stop> {
        let u = self.unsigned_vb()?;
        Ok(((u >> 1) as i32) ^ -((u & 1) as i32))
    }

    fn le(&mut self, n: usize) -> Result<i32, Stop> {
        let mut v: u32 = 0;
        for k in 0..n {
            v |= u32::from(self.byte()?) << (8 * k);
        }
        Ok(sign_extend(v, 8 * n as u32))
    }

    /// Decodes the values of `enc` starting with field `i` of `count` fields
    /// into `out`; returns how many fields it covered.
    pub fn values(
        &mut self,
        enc: Encoding,
        remaining: usize,
        group: usize,
        out: &mut Vec<i64>,
    ) -> Result<usize, Stop> {
        match enc {
            Encoding::SignedVb => out.push(i64::from(self.signed_vb()?)),
            Encoding::UnsignedVb => out.push(i64::from(self.unsigned_vb()?)),
            Encoding::Neg14Bit => {
                let u = self.unsigned_vb()? as u16;
                out.push(-i64::from(sign_extend(u32::from(u & 0x3fff), 14)));
            }
            Encoding::Null => out.push(0),
            Encoding::Tag8_8Svb => {
                let n = group.min(8);
                if n == 1 {
                    out.push(i64::from(self.signed_vb()?));
                } else {
                    let header = self.byte()?;
                    for k in 0..n {
                        let v = if header & (1 << k) != 0 {
                            self.signed_vb()?
                        } else {
                            0
                        };
                        out.push(i64::from(v));
                    }
                }
                return Ok(n);
            }
            Encoding::Tag2_3S32 | Encoding::Tag2_3SVariable => {
                let v = self.tag2_3(enc == Encoding::Tag2_3SVariable)?;
                let n = remaining.min(3);
                out.extend(v.iter().take(n).map(|&x| i64::from(x)));
                return Ok(n);
            }
            Encoding::Tag8_4S16 => {
                let v = self.tag8_4s16()?;
                let n = remaining.min(4);
                out.extend(v.iter().take(n).map(|&x| i64::from(x)));
                return Ok(n);
            }
        }
        Ok(1)
    }

    fn tag2_3(&mut self, variable: bool) -> Result<[i32; 3], Stop> {
        let lead = u32::from(self.byte()?);
        Ok(match (lead >> 6, variable) {
            (0, _) => [
                sign_extend((lead >> 4) & 3, 2),
                sign_extend((lead >> 2) & 3, 2),
                sign_extend(lead & 3, 2),
            ],
            (1, false) => {
                let b = u32::from(self.byte()?);
                [
                    sign_extend(lead & 0x0f, 4),
                    sign_extend(b >> 4, 4),
                    sign_extend(b & 0x0f, 4),
                ]
            }
            (1, true) => {
                let b = u32::from(self.byte()?);
                [
                    sign_extend((lead & 0x3e) >> 1, 5),
                    sign_extend(((lead & 1) << 4) | (b >> 4), 5),
                    sign_extend(b & 0x0f, 4),
                ]
            }
            (2, false) => {
                let b = u32::from(self.byte()?);
                let c = u32::from(self.byte()?);
                [
                    sign_extend(lead & 0x3f, 6),
                    sign_extend(b & 0x3f, 6),
                    sign_extend(c & 0x3f, 6),
                ]
            }
            (2, true) => {
                let b = u32::from(self.byte()?);
                let c = u32::from(self.byte()?);
                [
                    sign_extend(((lead & 0x3f) << 2) | (b >> 6), 8),
                    sign_extend(((b & 0x3f) << 1) | (c >> 7), 7),
                    sign_extend(c & 0x7f, 7),
                ]
            }
            _ => {
                let mut v = [0; 3];
                let mut sel = lead;
                for x in &mut v {
                    *x = self.le((sel & 3) as usize + 1)?;
                    sel >>= 2;
                }
                v
            }
        })
    }

    fn tag8_4s16(&mut self) -> Result<[i32; 4], Stop> {
        let mut sel = self.byte()?;
        let mut v = [0i32; 4];
        // Values are packed in nibbles, most significant first.
        let mut pending: Option<u8> = None;
        let mut nibble = |r: &mut Self| -> Result<u32, Stop> {
            match pending.take() {
                Some(low) => Ok(u32::from(low)),
                None => {
                    let b = r.byte()?;
                    pending = Some(b & 0x0f);
                    Ok(u32::from(b >> 4))
                }
            }
        };
        for x in &mut v {
            let nibbles = match sel & 3 {
                0 => 0,
                1 => 1,
                2 => 2,
                _ => 4,
            };
            let mut u = 0u32;
            for _ in 0..nibbles {
                u = (u << 4) | nibble(self)?;
            }
            *x = if nibbles == 0 {
                0
            } else {
                sign_extend(u, 4 * nibbles)
            };
            sel >>= 2;
        }
        Ok(v)
    }
}

/// The low `bits` bits of `v` as a signed number.
fn sign_extend(v: u32, bits: u32) -> i32 {
    let shift = 32 - bits;
    ((v << shift) as i32) >> shift
}

#[cfg(test)]
// The binary literals are grouped by the encodings' bit fields.
#[allow(clippy::unusual_byte_groupings)]
mod tests {
    use super::*;

    fn read(bytes: &[u8], enc: Encoding, n: usize) -> Vec<i64> {
        let mut r = Reader { bytes, pos: 0 };
        let mut out = Vec::new();
        r.values(enc, n, n, &mut out).unwrap();
        assert_eq!(r.pos, bytes.len(), "all bytes used");
        out
    }

    #[test]
    fn varints_and_zigzag() {
        assert_eq!(read(&[0x96, 0x01], Encoding::UnsignedVb, 1), [150]);
        assert_eq!(read(&[0x03], Encoding::SignedVb, 1), [-2]);
        assert_eq!(read(&[0x04], Encoding::SignedVb, 1), [2]);
        // 14-bit: 0x3fff is -1, negated: 1.
        assert_eq!(read(&[0xff, 0x7f], Encoding::Neg14Bit, 1), [1]);
        let mut r = Reader {
            bytes: &[0xff; 6],
            pos: 0,
        };
        assert!(matches!(r.unsigned_vb(), Err(Stop::LongVarint(0))));
        let mut r = Reader {
            bytes: &[0x80],
            pos: 0,
        };
        assert!(matches!(r.unsigned_vb(), Err(Stop::End)));
    }

    #[test]
    fn tag2_3s32_all_widths() {
        // 2 bits each: 01 11 10 -> 1, -1, -2.
        assert_eq!(read(&[0b00_01_11_10], Encoding::Tag2_3S32, 3), [1, -1, -2]);
        // 4 bits each.
        assert_eq!(
            read(&[0b01_00_0111, 0x8f], Encoding::Tag2_3S32, 3),
            [7, -8, -1]
        );
        // 6 bits each.
        assert_eq!(
            read(&[0b10_011111, 0x20, 0x01], Encoding::Tag2_3S32, 3),
            [31, -32, 1]
        );
        // Whole bytes: sizes 1, 2, 4 bytes (selectors 00, 01, 11 from the low bits).
        assert_eq!(
            read(
                &[0b11_11_01_00, 0xfe, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12],
                Encoding::Tag2_3S32,
                3
            ),
            [-2, 0x1234, 0x1234_5678]
        );
    }

    #[test]
    fn tag8_4s16_nibbles() {
        // Selectors (low bits first): 1 nibble, 2 nibbles, 0, 4 nibbles.
        let sel = 0b11_00_10_01;
        assert_eq!(
            read(&[sel, 0xf1, 0x2f, 0xed, 0xc0], Encoding::Tag8_4S16, 4),
            [-1, 0x12, 0, -0x124]
        );
    }

    #[test]
    fn tag8_8svb_groups() {
        assert_eq!(
            read(&[0b101, 0x02, 0x03], Encoding::Tag8_8Svb, 3),
            [1, 0, -2]
        );
        assert_eq!(read(&[0x05], Encoding::Tag8_8Svb, 1), [-3]);
    }
}
