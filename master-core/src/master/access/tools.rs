//! Register and SII access for tools: any ESC register of a slave, the SII image, SII
//! words, and the station alias (ETG.2010, spec-notes §sii.alias).

use crate::bus::DatagramData;
use crate::wire::register::address as reg;
use crate::wire::sii::checksum::CHECKSUM_OFFSET;
use crate::wire::sii::fixed::ALIAS_WORD;

use super::address::SlaveAddress;
use super::datagram::{fprd, fprd_u16, fprw, fpwr};
use crate::master::bringup::configure::eeprom;
use crate::master::context::Context;
use crate::master::error::MasterError;

/// Word 7: the checksum over words 0-6.
const CHECKSUM_WORD: u16 = (CHECKSUM_OFFSET / 2) as u16;

/// Reads `len` bytes at register `ado` of the slave at `address`.
pub(crate) async fn read_register(
    ctx: &Context,
    address: SlaveAddress,
    ado: u16,
    len: usize,
) -> Result<Vec<u8>, MasterError> {
    let station = ctx.station(address)?;
    Ok(fprd(&ctx.bus, station, ado, len, "register read")
        .await?
        .to_vec())
}

/// Writes `data` at register `ado` of the slave at `address`.
pub(crate) async fn write_register(
    ctx: &Context,
    address: SlaveAddress,
    ado: u16,
    data: Vec<u8>,
) -> Result<(), MasterError> {
    let station = ctx.station(address)?;
    fpwr(
        &ctx.bus,
        station,
        ado,
        DatagramData::from(data),
        "register write",
    )
    .await
}

/// Writes `data` at register `ado` of the slave at `address` and returns what was there
/// before, in one datagram.
pub(crate) async fn read_write_register(
    ctx: &Context,
    address: SlaveAddress,
    ado: u16,
    data: Vec<u8>,
) -> Result<Vec<u8>, MasterError> {
    let station = ctx.station(address)?;
    Ok(fprw(
        &ctx.bus,
        station,
        ado,
        DatagramData::from(data),
        "register read-write",
    )
    .await?
    .to_vec())
}

/// Reads the whole SII image of the slave at `address` from the slave.
pub(crate) async fn read_sii(ctx: &Context, address: SlaveAddress) -> Result<Vec<u8>, MasterError> {
    let station = ctx.station(address)?;
    let eeprom = eeprom(ctx, station);
    eeprom.take().await?;
    eeprom.read_image(ctx.config.max_sii_words).await
}

/// Writes `words` into the SII of the slave at `address`, from word `start` on. The
/// checksum is the caller's business here; [`set_alias`] keeps it valid.
pub(crate) async fn write_sii(
    ctx: &Context,
    address: SlaveAddress,
    start: u16,
    words: &[u16],
) -> Result<(), MasterError> {
    let station = ctx.station(address)?;
    let eeprom = eeprom(ctx, station);
    eeprom.take().await?;
    for (i, &value) in words.iter().enumerate() {
        let word = u16::try_from(i)
            .ok()
            .and_then(|i| start.checked_add(i))
            .ok_or(MasterError::InvalidArgument(
                "SII word address beyond 0xFFFF",
            ))?;
        eeprom.write(word, value).await?;
    }
    Ok(())
}

/// Sets the station alias of the slave at `address`: SII word 4 with the checksum of word 7
/// recomputed (as IgH's `ethercat alias` does), then an EEPROM reload so that the ESC's
/// alias register 0x0012 holds it at once. Returns the alias read back from 0x0012.
pub(crate) async fn set_alias(
    ctx: &Context,
    address: SlaveAddress,
    alias: u16,
) -> Result<u16, MasterError> {
    let record = ctx.resolve(address)?;
    let station = record.info.station;
    let eeprom = eeprom(ctx, station);
    eeprom.take().await?;
    let mut words = Vec::new();
    while words.len() <= usize::from(CHECKSUM_WORD) {
        let at = words.len() as u16;
        let chunk = eeprom.read(at).await?;
        if chunk.is_empty() {
            return Err(MasterError::Eeprom {
                station,
                reason: "returned no data",
            });
        }
        words.extend(chunk);
    }
    let mut fixed: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
    crate::wire::sii::set_alias(&mut fixed, alias).map_err(|source| MasterError::Malformed {
        position: record.info.position,
        what: "SII configuration area",
        source,
    })?;
    // Only words 4 and 7 change (spec-notes §sii.alias); write back just those.
    let word_at = |w: u16| {
        let at = usize::from(w) * 2;
        let bytes: [u8; 2] = fixed
            .get(at..at + 2)
            .and_then(|b| b.try_into().ok())
            .unwrap_or_default();
        u16::from_le_bytes(bytes)
    };
    eeprom.write(ALIAS_WORD, word_at(ALIAS_WORD)).await?;
    eeprom.write(CHECKSUM_WORD, word_at(CHECKSUM_WORD)).await?;
    // Verified by reading back: a write the EEPROM did not take (write protection, a busy
    // PDI) must not pass for done.
    for word in [ALIAS_WORD, CHECKSUM_WORD] {
        if eeprom.read(word).await?.first() != Some(&word_at(word)) {
            return Err(MasterError::Eeprom {
                station,
                reason: "alias not written: SII words 4 and 7 read back differ",
            });
        }
    }
    eeprom.reload().await?;
    let now = fprd_u16(&ctx.bus, station, reg::STATION_ALIAS, "station alias").await?;
    if now != alias {
        return Err(MasterError::Eeprom {
            station,
            reason: "alias written to the SII, but the alias register 0x0012 differs after the reload",
        });
    }
    ctx.update(record.info.position, |r| {
        r.info.alias = now;
        if r.sii.len() >= fixed.len() {
            r.sii[..fixed.len()].copy_from_slice(&fixed);
        }
    });
    Ok(now)
}
