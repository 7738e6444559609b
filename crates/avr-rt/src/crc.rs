//! CRC-16/CCITT-FALSE (polynomial 0x1021, initial value 0xFFFF, no reflection,
//! no final XOR), computed a byte at a time without a table.

/// The CRC-16/CCITT-FALSE of `data`.
///
/// ```
/// assert_eq!(kestrel_avr_rt::crc16(b"123456789"), 0x29B1);
/// ```
pub const fn crc16(data: &[u8]) -> u16 {
    crc16_update(0xFFFF, data)
}

/// Continues a CRC-16/CCITT-FALSE computation from `crc` over `data`.
pub const fn crc16_update(mut crc: u16, data: &[u8]) -> u16 {
    // Loop-free byte step (no table: LLVM would turn the bitwise loop into a
    // 512-byte lookup table, which the AVR would keep in RAM).
    let mut i = 0;
    while i < data.len() {
        let mut x = ((crc >> 8) as u8 ^ data[i]) as u16;
        x ^= x >> 4;
        crc = (crc << 8) ^ (x << 12) ^ (x << 5) ^ x;
        i += 1;
    }
    crc
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An independent, table-driven implementation to compare with.
    fn crc16_table(data: &[u8]) -> u16 {
        let mut table = [0u16; 256];
        for (i, t) in table.iter_mut().enumerate() {
            let mut c = (i as u16) << 8;
            for _ in 0..8 {
                c = if c & 0x8000 != 0 {
                    (c << 1) ^ 0x1021
                } else {
                    c << 1
                };
            }
            *t = c;
        }
        let mut crc = 0xFFFFu16;
        for &b in data {
            crc = (crc << 8) ^ table[((crc >> 8) as u8 ^ b) as usize];
        }
        crc
    }

    #[test]
    fn check_value() {
        assert_eq!(crc16(b"123456789"), 0x29B1);
        assert_eq!(crc16(b""), 0xFFFF);
    }

    proptest::proptest! {
        #[test]
        fn matches_table_driven(data in proptest::collection::vec(proptest::num::u8::ANY, 0..64)) {
            proptest::prop_assert_eq!(crc16(&data), crc16_table(&data));
        }

        #[test]
        fn detects_every_single_bit_flip(data in proptest::collection::vec(proptest::num::u8::ANY, 1..40), bit in 0usize..320) {
            let bit = bit % (data.len() * 8);
            let mut bad = data.clone();
            bad[bit / 8] ^= 1 << (bit % 8);
            proptest::prop_assert_ne!(crc16(&data), crc16(&bad));
        }
    }
}
