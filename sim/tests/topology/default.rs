//! The built-in topology: it builds, its TOML file matches it, and every slave's SII says
//! what the description declares.

use ecat_wire::sii::SiiImage;
use ecat_wire::sii::fixed::MailboxProtocols;
use sim::topology::{SIM_VENDOR_ID, Topology, build_with_handles};

const DEFAULT_TOML: &str = "topologies/default.toml";

#[test]
fn default_file_equals_the_built_in() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(DEFAULT_TOML);
    let built_in = Topology::default_segment();
    if std::env::var_os("ECATD_BLESS").is_some() {
        let header = "# The built-in simulated segment (sim::topology::Topology::default_segment).\n\
                      # Regenerate: ECATD_BLESS=1 cargo test -p sim --test topology_default\n\
                      # vendor_id 3758096385 = 0xE0000001, a simulation-only ID (see SIM_VENDOR_ID).\n\
                      # The DI8's inputs are wired to the DO8's outputs (wired_to = 1, a ring\n\
                      # position); remove the line for free inputs (src/topology/model.rs).\n\n";
        std::fs::write(&path, format!("{header}{}", built_in.to_toml().unwrap())).unwrap();
    }
    let text = std::fs::read_to_string(&path).unwrap();
    assert_eq!(Topology::from_toml(&text).unwrap(), built_in);
}

#[test]
fn default_segment_builds_with_valid_sii() {
    let topology = Topology::default_segment();
    let built = build_with_handles(&topology).unwrap();
    assert_eq!(built.segment.len(), 5);
    for (p, spec) in topology.slaves.iter().enumerate() {
        let esc = built.segment.esc(p).unwrap();
        let sii = SiiImage::parse(esc.sii()).unwrap();
        assert!(sii.checksum_ok, "slave {p}");
        assert_eq!(sii.fixed.vendor_id, SIM_VENDOR_ID);
        assert_eq!(sii.fixed.product_code, spec.product_code);
        assert_eq!(sii.fixed.revision, spec.revision);
        assert_eq!(sii.fixed.serial, spec.serial);
        assert_eq!(sii.name(), Some(spec.name.as_str()));
        match spec.mailbox {
            Some(m) => {
                assert_eq!(sii.fixed.std_rx_mailbox.offset, 0x1000);
                assert_eq!(sii.fixed.std_rx_mailbox.size, m.rx_size);
                assert_eq!(sii.fixed.std_tx_mailbox.offset, 0x1000 + m.rx_size);
                assert_eq!(sii.fixed.std_tx_mailbox.size, m.tx_size);
            }
            None => assert_eq!(sii.fixed.std_rx_mailbox.size, 0),
        }
        assert_eq!(
            sii.rxpdo.len() + sii.txpdo.len(),
            spec.pdos.len(),
            "slave {p}"
        );
    }
    let drive = SiiImage::parse(built.segment.esc(0).unwrap().sii()).unwrap();
    let bits = MailboxProtocols::COE
        | MailboxProtocols::SOE
        | MailboxProtocols::FOE
        | MailboxProtocols::VOE
        | MailboxProtocols::EOE;
    assert_eq!(drive.fixed.mailbox_protocols.0, bits);
    // SM2 outputs 6 bytes, SM3 inputs 6 bytes, as the PDOs add up.
    assert_eq!(drive.syncm[2].length, 6);
    assert_eq!(drive.syncm[3].length, 6);
    let do8 = SiiImage::parse(built.segment.esc(1).unwrap().sii()).unwrap();
    assert_eq!(do8.fixed.mailbox_protocols.0, 0);
    assert_eq!(do8.syncm[0].length, 1);
    let eoe = SiiImage::parse(built.segment.esc(4).unwrap().sii()).unwrap();
    assert_eq!(eoe.fixed.mailbox_protocols.0, MailboxProtocols::EOE);
    // The drive's dictionary reports its assigned process data.
    let dict = built.slaves[0].dictionary.clone().unwrap();
    let dict = sim::device::coe::lock_dictionary(&dict);
    assert_eq!(dict.get::<u32>(0x1018, 1).unwrap(), SIM_VENDOR_ID);
    assert_eq!(dict.process_data_bits(0x1C12), 48);
    assert_eq!(dict.process_data_bits(0x1C13), 48);
}

#[test]
fn drive_process_data_follows_its_assignment() {
    let built = build_with_handles(&Topology::default_segment()).unwrap();
    let sizes =
        |b: &sim::topology::Built| b.segment.slave(0).unwrap().device().process_data_sizes();
    assert_eq!((sizes(&built).outputs, sizes(&built).inputs), (6, 6));
    let dict = built.slaves[0].dictionary.clone().unwrap();
    // A master switching the TxPDO assignment off (0x1C13:00 = 0) in PREOP.
    sim::device::coe::lock_dictionary(&dict)
        .set(0x1C13, 0, &0u8)
        .unwrap();
    assert_eq!((sizes(&built).outputs, sizes(&built).inputs), (6, 0));
}

#[test]
fn repeated_segment_cycles_the_default_slaves_with_own_serials() {
    let topology = Topology::repeated(12);
    let built = build_with_handles(&topology).unwrap();
    assert_eq!(built.segment.len(), 12);
    let default = Topology::default_segment();
    for p in 0..12 {
        let sii = SiiImage::parse(built.segment.esc(p).unwrap().sii()).unwrap();
        assert!(sii.checksum_ok, "slave {p}");
        assert_eq!(sii.fixed.product_code, default.slaves[p % 5].product_code);
        assert_eq!(sii.fixed.serial, p as u32 + 1, "slave {p}");
    }
    assert!(
        topology
            .slaves
            .iter()
            .all(|s| s.eoe.is_none_or(|e| e.ip.is_none()))
    );
}
