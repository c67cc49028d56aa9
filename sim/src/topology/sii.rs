//! A slave's SII image from its description (ETG.1000.6 §5.4, ETG.2010; spec-notes §sii,
//! §sii.categories): identity and mailbox areas, GENERAL, FMMU, SYNCM and the TXPDO/RXPDO
//! categories, with the SyncManager layout the ESC checks (the memory layout described in
//! `build.rs`).

use std::collections::BTreeSet;

use ecat_wire::WireError;
use ecat_wire::sii::SiiBuilder;
use ecat_wire::sii::fixed::{MailboxProtocols, SiiFixedRepr, SiiMailboxArea};
use ecat_wire::sii::fmmu::FmmuUsage;
use ecat_wire::sii::general::{CoeDetails, GeneralRepr, PhysicalPorts};
use ecat_wire::sii::pdo::{Pdo, PdoFlags, SiiPdoEntry};
use ecat_wire::sii::syncm::{SyncmEnable, SyncmEntry, SyncmType};

use super::dictionary::data_type;
use super::model::{PdoSpec, SlaveSpec};

/// SM lengths and start addresses: mailbox SMs, then one per SM number the PDOs use.
fn syncms(spec: &SlaveSpec) -> Vec<SyncmEntry> {
    let mut entries = Vec::new();
    let mut next = 0x1000u16;
    if let Some(mbx) = spec.mailbox {
        entries.push(SyncmEntry {
            start: mbx.sm0_start(),
            length: mbx.rx_size,
            control: 0x26,
            status: 0,
            enable: SyncmEnable(0x01),
            sm_type: SyncmType::MailboxOut,
        });
        entries.push(SyncmEntry {
            start: mbx.sm1_start(),
            length: mbx.tx_size,
            control: 0x22,
            status: 0,
            enable: SyncmEnable(0x01),
            sm_type: SyncmType::MailboxIn,
        });
        next = mbx
            .sm1_start()
            .saturating_add(mbx.tx_size)
            .next_multiple_of(0x80);
    }
    let used: BTreeSet<u8> = spec.pdos.iter().map(|p| p.sm).collect();
    for sm in used {
        while entries.len() < usize::from(sm) {
            entries.push(SyncmEntry {
                start: 0,
                length: 0,
                control: 0,
                status: 0,
                enable: SyncmEnable(0),
                sm_type: SyncmType::Unspecified,
            });
        }
        let pdos: Vec<&PdoSpec> = spec.pdos.iter().filter(|p| p.sm == sm).collect();
        let bits: u32 = pdos.iter().map(|p| p.bits()).sum();
        let length = u16::try_from(bits.div_ceil(8)).unwrap_or(u16::MAX);
        let outputs = pdos.first().is_some_and(|p| p.is_rx());
        entries.push(SyncmEntry {
            start: next,
            length,
            control: if outputs { 0x64 } else { 0x20 },
            status: 0,
            enable: SyncmEnable(u8::from(length > 0)),
            sm_type: if outputs {
                SyncmType::Outputs
            } else {
                SyncmType::Inputs
            },
        });
        next = next.saturating_add((length * 3).next_multiple_of(0x80).max(0x80));
    }
    entries
}

/// The SII image of the slave, advertising `protocols` (the mailbox protocol bits).
pub(crate) fn sii(spec: &SlaveSpec, protocols: u16) -> Result<Vec<u8>, WireError> {
    let (rx, tx) = match spec.mailbox {
        Some(m) => (
            SiiMailboxArea {
                offset: m.sm0_start(),
                size: m.rx_size,
            },
            SiiMailboxArea {
                offset: m.sm1_start(),
                size: m.tx_size,
            },
        ),
        None => (SiiMailboxArea::default(), SiiMailboxArea::default()),
    };
    let mut b = SiiBuilder::new(SiiFixedRepr {
        pdi_control: 0x0005,
        alias: spec.alias,
        vendor_id: spec.vendor_id,
        product_code: spec.product_code,
        revision: spec.revision,
        serial: spec.serial,
        boot_rx_mailbox: rx,
        boot_tx_mailbox: tx,
        std_rx_mailbox: rx,
        std_tx_mailbox: tx,
        mailbox_protocols: MailboxProtocols(protocols),
        version: 1,
        ..SiiFixedRepr::default()
    });
    let name = b.add_string(&spec.name)?;
    let group = b.add_string("ECATD-SIM")?;
    let coe = protocols & MailboxProtocols::COE != 0;
    b.general = Some(GeneralRepr {
        group_idx: group,
        order_idx: name,
        name_idx: name,
        // SDO, SDO Information, PDO assignment, PDO configuration, complete access.
        coe_details: CoeDetails(if coe { 0x2F } else { 0 }),
        foe_details: u8::from(protocols & MailboxProtocols::FOE != 0),
        eoe_details: u8::from(protocols & MailboxProtocols::EOE != 0),
        soe_channels: if protocols & MailboxProtocols::SOE != 0 {
            spec.soe_drives
        } else {
            0
        },
        ebus_current_ma: 0,
        // Ports 0 and 1: MII.
        physical_ports: PhysicalPorts(0x0011),
        ..GeneralRepr::default()
    });
    let has_out = spec.pdos.iter().any(PdoSpec::is_rx);
    let has_in = spec.pdos.iter().any(|p| !p.is_rx());
    if has_out {
        b.fmmu.push(FmmuUsage::Outputs);
    }
    if has_in {
        b.fmmu.push(FmmuUsage::Inputs);
    }
    if spec.mailbox.is_some() {
        b.fmmu.push(FmmuUsage::SyncManagerStatus);
    }
    b.syncm = syncms(spec);
    for pdo in &spec.pdos {
        let pdo_name = b.add_string(&pdo.name)?;
        let mut entries = Vec::new();
        for e in &pdo.entries {
            let entry_name = b.add_string(&e.name)?;
            entries.push(SiiPdoEntry {
                index: e.index,
                subindex: e.subindex,
                name_idx: entry_name,
                data_type: data_type(&e.data_type).map_or(0, |dt| u16::from(dt) as u8),
                bit_length: e.bits,
                flags: 0,
            });
        }
        let sii_pdo = Pdo {
            index: pdo.index,
            sync_manager: pdo.sm,
            dc_sync: 0,
            name_idx: pdo_name,
            // Bit 4: mandatory... none set: every PDO is the default assignment.
            flags: PdoFlags(0),
            entries,
        };
        if pdo.is_rx() {
            b.rxpdo.push(sii_pdo);
        } else {
            b.txpdo.push(sii_pdo);
        }
    }
    b.build()
}
