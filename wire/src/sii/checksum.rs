//! The SII checksum, word 7 (ETG.2010, spec-notes §sii.fixed).
//!
//! CRC-8, polynomial 0x07, initial value 0xFF, MSB first, no reflection, no final XOR, over
//! the 14 bytes of words 0-6. The result is the low byte of word 7; the high byte is 0.

use crc::{Algorithm, Crc};

use crate::error::{Result, need};

/// The CRC-8 variant of the SII fixed area (ETG.2010, spec-notes §sii.fixed).
///
/// `check` is the CRC of the ASCII string "123456789", as the catalogue convention requires;
/// `residue` is 0 because there is no final XOR.
pub const SII_CRC8: Algorithm<u8> = Algorithm {
    width: 8,
    poly: 0x07,
    init: 0xFF,
    refin: false,
    refout: false,
    xorout: 0x00,
    check: 0xFB,
    residue: 0x00,
};

const CRC: Crc<u8> = Crc::<u8>::new(&SII_CRC8);

/// Bytes covered by the checksum: words 0-6.
pub const CHECKSUM_SPAN: usize = 14;
/// Byte offset of the checksum (low byte of word 7).
pub const CHECKSUM_OFFSET: usize = 14;

/// CRC-8 (ETG.2010, spec-notes §sii.fixed) of arbitrary bytes.
pub fn crc8(bytes: &[u8]) -> u8 {
    CRC.checksum(bytes)
}

/// The checksum of an image's fixed area: the CRC of its first 14 bytes.
pub fn checksum(image: &[u8]) -> Result<u8> {
    need("SII checksum area", image, CHECKSUM_SPAN)?;
    Ok(crc8(&image[..CHECKSUM_SPAN]))
}

/// Whether the low byte of word 7 matches the CRC of words 0-6. The high byte is not
/// checked (ESCs only compare the low byte; IgH leaves the high byte untouched).
pub fn checksum_ok(image: &[u8]) -> Result<bool> {
    need("SII checksum", image, CHECKSUM_OFFSET + 2)?;
    Ok(checksum(image)? == image[CHECKSUM_OFFSET])
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Words 0-6 of three real dumps and their checksums (ETG.2010, spec-notes §sii.fixed).
    const DUMPS: [([u8; 14], u8); 3] = [
        // EL2004
        (
            [
                0x04, 0x01, 0x00, 0x00, 0x00, 0x00, 0x0f, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
            ],
            0xD8,
        ),
        // EK1100
        (
            [
                0x00, 0x0d, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
            ],
            0x46,
        ),
        // EL2262
        (
            [
                0x06, 0x05, 0x00, 0x00, 0x10, 0x00, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
            ],
            0x2B,
        ),
    ];

    #[test]
    fn real_dumps() {
        for (words, crc) in DUMPS {
            assert_eq!(checksum(&words).unwrap(), crc);
            let mut image = words.to_vec();
            image.extend_from_slice(&[crc, 0x00]);
            assert!(checksum_ok(&image).unwrap());
            image[14] ^= 1;
            assert!(!checksum_ok(&image).unwrap());
        }
    }

    #[test]
    fn catalogue_check_value() {
        assert_eq!(crc8(b"123456789"), SII_CRC8.check);
    }

    #[test]
    fn truncated() {
        assert!(checksum(&[0u8; 13]).is_err());
        assert!(checksum_ok(&[0u8; 15]).is_err());
    }

    proptest! {
        #[test]
        fn never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..20)) {
            let _ = checksum(&bytes);
            let _ = checksum_ok(&bytes);
        }
    }
}
