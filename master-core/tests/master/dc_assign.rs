//! SYNC activation follows the slave's SII: a slave whose DC category names an
//! AssignActivate word gets it in 0x0980/0x0981; slaves without keep the default (cyclic
//! operation + SYNC0).

use crate::master_support;

use std::time::Duration;

use master_core::master::{DcSettings, MasterConfig, SlaveAddress};
use master_core::wire::register::address as reg;
use master_core::wire::sii::dc::DcEntry;
use master_core::wire::sii::{SiiBuilder, SiiImage};
use master_support::{block_on, rig};
use sim::topology::Topology;

/// SYNC0 + SYNC1 + cyclic operation in 0x0981, 0x0980 = 0: what an SII may ask for.
const ASSIGN: u16 = 0x0700;

#[test]
fn the_sii_s_assign_activate_is_written_and_others_keep_the_default() {
    let rig = rig(
        Topology::default_segment(),
        MasterConfig {
            watch_interval: None,
            dc: DcSettings {
                sync0_cycle: Some(Duration::from_millis(1)),
                ..DcSettings::default()
            },
            ..MasterConfig::default()
        },
    );
    let m = rig.master();
    let report = block_on(m.scan()).expect("scan");
    assert!(report.failures.is_empty(), "{:?}", report.failures);
    let drive = SlaveAddress::Position(0);
    let original = m.sii_image(drive).expect("SII");
    let parsed = SiiImage::parse(&original).expect("parses");
    assert!(
        parsed.dc.is_empty(),
        "the simulated drive's SII has no DC category yet"
    );
    let mut builder = SiiBuilder::from_image(&parsed);
    builder.dc = vec![DcEntry {
        assign_activate: ASSIGN,
        ..DcEntry::default()
    }];
    let updated = builder.build().expect("builds");
    // Write from the first word that changed on.
    let words = |image: &[u8]| -> Vec<u16> {
        image
            .chunks(2)
            .map(|c| u16::from_le_bytes([c[0], *c.get(1).unwrap_or(&0)]))
            .collect()
    };
    let (old, new) = (words(&original), words(&updated));
    let first = old
        .iter()
        .zip(&new)
        .position(|(a, b)| a != b)
        .unwrap_or(old.len().min(new.len()));
    block_on(m.write_sii(drive, first as u16, &new[first..])).expect("SII write");

    let report = block_on(m.scan()).expect("rescan");
    assert!(report.failures.is_empty(), "{:?}", report.failures);
    let reread = SiiImage::parse(&m.sii_image(drive).unwrap())
        .unwrap()
        .dc
        .first()
        .map(|d| d.assign_activate);
    assert_eq!(reread, Some(ASSIGN), "the rescan read the new DC category");
    let segment = rig.segment();
    let esc = segment.esc(0).unwrap();
    assert_eq!(
        esc.read_u8(reg::DC_ACTIVATION),
        0x07,
        "AssignActivate high byte"
    );
    assert_eq!(esc.read_u8(reg::DC_CYCLIC_UNIT_CONTROL), 0x00);
    // DO8 has process data and no DC category: the default.
    assert_eq!(segment.esc(1).unwrap().read_u8(reg::DC_ACTIVATION), 0x03);
}
