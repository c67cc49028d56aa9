//! Mapping each mailbox slave's "mailbox full" bit into the cyclic frame (the FMMU of
//! spec-notes §capture for 0x080D): bit 3 of SM1's status byte goes to bit *p* of the logical
//! status area for the slave at ring position *p*. The FMMU is written with the mailbox
//! SyncManagers (INIT → PREOP), so the bit is read from the moment the mailbox works.

use crate::wire::register::address::{fmmu as fmmu_address, sync_manager_status};
use crate::wire::register::{Fmmu, FmmuRepr};
use crate::wire::sii::SiiImage;
use crate::wire::sii::fmmu::FmmuUsage;

use super::image::STATUS_BASE;
use crate::master::access::datagram::fpwr;
use crate::master::context::Context;
use crate::master::error::MasterError;
use crate::master::info::SlaveInfo;

/// Bit of the SM status byte that says "mailbox full" (ETG.1000.4, spec-notes §esc.sm).
const MAILBOX_FULL_BIT: u8 = 3;

/// The send mailbox (slave → master) is SyncManager 1.
const SEND_MAILBOX_SM: u8 = 1;

/// The FMMU that carries the status bit: the one the SII marks for SyncManager status,
/// else the ESC's last FMMU unless the SII gives it to process data. `None` on ESCs with
/// fewer than three FMMUs (they need theirs for outputs and inputs).
pub(crate) fn status_fmmu(sii: &SiiImage<'_>, fmmu_count: u8) -> Option<u8> {
    let count = fmmu_count.min(16);
    let marked = sii
        .fmmu
        .iter()
        .position(|&u| u == FmmuUsage::SyncManagerStatus)
        .and_then(|i| u8::try_from(i).ok())
        .filter(|&i| i < count);
    marked.or_else(|| {
        let last = count.checked_sub(1).filter(|_| count >= 3)?;
        let taken = matches!(
            sii.fmmu.get(usize::from(last)),
            Some(FmmuUsage::Outputs | FmmuUsage::Inputs)
        );
        (!taken).then_some(last)
    })
}

/// The mapping of slave `position`'s "mailbox full" bit.
pub(crate) fn status_mapping(position: u16) -> Option<FmmuRepr> {
    let physical_start = sync_manager_status(SEND_MAILBOX_SM)?;
    let bit = (position % 8) as u8;
    Some(FmmuRepr {
        logical_start: STATUS_BASE + u32::from(position / 8),
        length: 1,
        logical_start_bit: bit,
        logical_stop_bit: bit,
        physical_start,
        physical_start_bit: MAILBOX_FULL_BIT,
        read: true,
        write: false,
        enable: true,
    })
}

/// Maps the "mailbox full" bit of the slave of `info` (which has a mailbox) if the
/// master is configured to and the slave has an FMMU for it; the cyclic frame reads it
/// from then on.
pub(crate) async fn map(
    ctx: &Context,
    info: &SlaveInfo,
    sii: &SiiImage<'_>,
) -> Result<(), MasterError> {
    if !ctx.config.map_mailbox_status || info.mailbox.is_none() {
        return Ok(());
    }
    let (Some(index), Some(mapping)) = (
        status_fmmu(sii, info.esc.fmmu_count),
        status_mapping(info.position),
    ) else {
        return Ok(());
    };
    let mut bytes = [0u8; 16];
    mapping
        .emit(&mut Fmmu::new_unchecked(&mut bytes[..]))
        .map_err(|source| MasterError::Malformed {
            position: info.position,
            what: "mailbox-status FMMU",
            source,
        })?;
    let ado = fmmu_address(index).ok_or(MasterError::InvalidArgument("FMMU number"))?;
    fpwr(&ctx.bus, info.station, ado, bytes, "mailbox-status FMMU").await?;
    ctx.image.map_status(info.position, Some(info.station));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::sii::SiiBuilder;
    use crate::wire::sii::fixed::SiiFixedRepr;

    fn image(fmmu: Vec<FmmuUsage>) -> Vec<u8> {
        let mut b = SiiBuilder::new(SiiFixedRepr::default());
        b.fmmu = fmmu;
        b.build().unwrap()
    }

    #[test]
    fn the_sii_s_status_fmmu_else_the_last_free_one() {
        let marked = image(vec![
            FmmuUsage::Outputs,
            FmmuUsage::Inputs,
            FmmuUsage::SyncManagerStatus,
        ]);
        assert_eq!(status_fmmu(&SiiImage::parse(&marked).unwrap(), 8), Some(2));
        let plain = image(Vec::new());
        assert_eq!(status_fmmu(&SiiImage::parse(&plain).unwrap(), 8), Some(7));
        assert_eq!(status_fmmu(&SiiImage::parse(&plain).unwrap(), 2), None);
    }

    #[test]
    fn position_p_maps_to_bit_p_of_the_status_area() {
        let m = status_mapping(10).unwrap();
        assert_eq!(
            (m.logical_start, m.logical_start_bit, m.logical_stop_bit),
            (STATUS_BASE + 1, 2, 2)
        );
        assert_eq!((m.physical_start, m.physical_start_bit), (0x080D, 3));
        assert_eq!(m.bit_count(), 1);
        assert!(m.read && !m.write && m.enable);
    }
}
