//! The SII checksum kept valid by writes through the API: the low byte of word 7 is the
//! CRC-8 of words 0-6 (ETG.2010, spec-notes §sii.fixed); an ESC whose checksum does not
//! match refuses its configuration area at the next power-up.

use master_core::master::{Master, SlaveAddress};
use master_core::wire::sii::checksum::{CHECKSUM_SPAN, crc8};

use super::{ApiError, Result};

/// The checksum word.
pub const CHECKSUM_WORD: u16 = 7;

/// For a write of `words` from word `start`: `None` when it leaves words 0-7 alone or
/// writes a matching word 7 itself; `Some(word 7)` to write after it (the checksum
/// recomputed, the high byte kept); an error, before anything is written, when it writes a
/// word 7 that does not match.
pub async fn keep_valid(
    master: &Master,
    address: SlaveAddress,
    start: u16,
    words: &[u16],
) -> Result<Option<u16>> {
    if start > CHECKSUM_WORD {
        return Ok(None);
    }
    let image = master.read_sii(address).await?;
    let mut fixed: Vec<u16> = image
        .chunks_exact(2)
        .take(usize::from(CHECKSUM_WORD) + 1)
        .map(|w| u16::from_le_bytes([w[0], w[1]]))
        .collect();
    if fixed.len() <= usize::from(CHECKSUM_WORD) {
        return Err(ApiError::invalid(
            "the slave's SII is shorter than its configuration area (words 0-7)",
        ));
    }
    for (i, &value) in words.iter().enumerate() {
        if let Some(slot) = fixed.get_mut(usize::from(start) + i) {
            *slot = value;
        }
    }
    let bytes: Vec<u8> = fixed.iter().flat_map(|w| w.to_le_bytes()).collect();
    let crc = crc8(&bytes[..CHECKSUM_SPAN]);
    let word7 = fixed[usize::from(CHECKSUM_WORD)];
    let writes_word7 = usize::from(start) + words.len() > usize::from(CHECKSUM_WORD);
    if writes_word7 {
        if word7 & 0xFF == u16::from(crc) {
            return Ok(None);
        }
        return Err(ApiError::invalid_field(
            "data",
            format!(
                "SII checksum 0x{:02x} (word 7, low byte) does not match words 0-6 (CRC \
                 0x{crc:02x}); nothing written (force writes it anyway)",
                word7 & 0xFF
            ),
        ));
    }
    Ok(Some((word7 & 0xFF00) | u16::from(crc)))
}
