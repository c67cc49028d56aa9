//! The master reads CoE slaves' process-data layout through their mailbox: the PDO
//! assignment (0x1C12/0x1C13) and the mapping objects, as the simulator's dictionary holds
//! them; slaves without CoE keep the SII's layout.

use crate::master_support;

use master_core::master::{MasterConfig, PdoEntryInfo, PdoInfo, SlaveAddress};
use master_core::od::StaticDictionary;
use master_core::od::standard::{RX_PDO_ASSIGN, TX_PDO_ASSIGN};
use master_support::{block_on, rig};
use sim::device::coe::lock_dictionary;
use sim::topology::Topology;

/// A PDO as (index, SyncManager, entries as (index, subindex, bits)).
type Shape = (u16, u8, Vec<(u16, u8, u8)>);

/// The PDOs the dictionary assigns to `sm` through `assign`, with their entries.
fn expected_pdos(dict: &StaticDictionary, assign: u16, sm: u8) -> Vec<Shape> {
    dict.assigned_pdos(assign)
        .into_iter()
        .map(|pdo| {
            let entries = dict
                .mapped_entries(pdo)
                .into_iter()
                .map(|e| (e.index, e.subindex, e.bit_length))
                .collect();
            (pdo, sm, entries)
        })
        .collect()
}

fn shape(pdos: &[PdoInfo]) -> Vec<Shape> {
    pdos.iter()
        .map(|p| {
            let entries = p
                .entries
                .iter()
                .map(|e: &PdoEntryInfo| (e.index, e.subindex, e.bit_length))
                .collect();
            (p.index, p.sync_manager, entries)
        })
        .collect()
}

#[test]
fn the_drive_s_pdo_mapping_is_read_from_its_dictionary() {
    let rig = rig(Topology::default_segment(), MasterConfig::default());
    // Shrink the drive's RxPDO in its dictionary only (the SII still describes 6 output
    // bytes): a layout that follows CoE sees 2.
    let dict = rig.handles[0].dictionary.clone().expect("drive dictionary");
    lock_dictionary(&dict)
        .set(0x1600, 0, &1u8)
        .expect("0x1600:00");
    let report = block_on(rig.master().scan()).expect("scan");
    let drive = SlaveAddress::Position(0);
    assert!(report.failures.is_empty(), "{:?}", report.failures);
    let layout = rig.master().process_data_layout(drive).expect("layout");
    let (rx, tx) = {
        let d = lock_dictionary(&dict);
        (
            expected_pdos(&d, RX_PDO_ASSIGN, 2),
            expected_pdos(&d, TX_PDO_ASSIGN, 3),
        )
    };
    assert_eq!(rx, vec![(0x1600, 2, vec![(0x6040, 0, 16)])]);
    assert_eq!(shape(&layout.pdos), [rx, tx].concat());
    // Data types come from the SII's description of the same objects.
    let statusword = layout.pdos[1].entries[0];
    assert_eq!(
        statusword.data_type,
        Some(master_core::wire::coe::DataType::Unsigned16)
    );

    // SyncManager lengths and the image share equal what the simulated drive exchanges.
    let sizes = rig
        .segment()
        .slave(0)
        .unwrap()
        .device()
        .process_data_sizes();
    assert_eq!(layout.outputs_len(), usize::from(sizes.outputs));
    assert_eq!(layout.inputs_len(), usize::from(sizes.inputs));
    let info = rig.master().slave(drive).unwrap();
    assert_eq!(
        (info.process_data.outputs, info.process_data.inputs),
        (sizes.outputs, sizes.inputs)
    );
    assert_eq!((sizes.outputs, sizes.inputs), (2, 6));
    assert_eq!(
        info.al_state,
        master_core::wire::register::AlState::Op,
        "the drive accepts the layout read from it"
    );
}

#[test]
fn slaves_without_coe_keep_the_sii_layout() {
    let topology = Topology::default_segment();
    let rig = rig(topology.clone(), MasterConfig::default());
    let report = block_on(rig.master().scan()).expect("scan");
    assert!(report.failures.is_empty(), "{:?}", report.failures);
    // DO8 and DI8: one PDO of eight 1-bit entries each, on SM0, as the topology says.
    for position in [1usize, 2] {
        let layout = rig
            .master()
            .process_data_layout(SlaveAddress::Position(position as u16))
            .unwrap();
        let spec = &topology.slaves[position].pdos[0];
        let expected: Vec<(u16, u8, u8)> = spec
            .entries
            .iter()
            .map(|e| (e.index, e.subindex, e.bits))
            .collect();
        let got = shape(&layout.pdos);
        assert_eq!(got, vec![(spec.index, spec.sm, expected)]);
        assert_eq!(
            layout.pdos[0].entries[0].data_type,
            Some(master_core::wire::coe::DataType::Boolean)
        );
    }
    // The CoE store assigns nothing: no process data at all.
    let store = rig
        .master()
        .process_data_layout(SlaveAddress::Position(3))
        .unwrap();
    assert!(store.sync_managers.is_empty() && store.pdos.is_empty());
}

/// The drive's CoE service, refusing complete access as a slave without it does (SDO abort
/// 0x06010000 in an SDO response), and counting the refusals.
struct NoCompleteAccess {
    coe: sim::device::CoeService,
    refused: std::sync::Arc<std::sync::atomic::AtomicUsize>,
}

impl sim::device::mailbox::MailboxService for NoCompleteAccess {
    fn mailbox_type(&self) -> master_core::wire::mailbox::MailboxType {
        master_core::wire::mailbox::MailboxType::Coe
    }

    fn handle(
        &mut self,
        request: &master_core::wire::mailbox::MailboxHeader,
        data: &[u8],
        ctx: &sim::device::DeviceContext,
        replies: &mut sim::device::mailbox::ReplySink,
    ) {
        use master_core::wire::Emit;
        use master_core::wire::coe::{AbortCode, CoeFrame, CoeRepr, SdoRequest, SdoResponse};
        let parsed = CoeFrame::new_checked(data)
            .ok()
            .and_then(|f| CoeRepr::parse(&f).ok());
        if let Some(CoeRepr::SdoRequest(SdoRequest::InitiateUpload {
            index,
            subindex,
            complete_access: true,
        })) = parsed
        {
            self.refused
                .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            let abort = CoeRepr::SdoResponse(SdoResponse::Abort {
                index,
                subindex,
                code: AbortCode::UnsupportedAccess,
            });
            let built = abort.to_vec();
            let _ = replies.send_emitted(built);
            return;
        }
        self.coe.handle(request, data, ctx, replies);
    }

    fn poll(
        &mut self,
        ctx: &sim::device::DeviceContext,
        replies: &mut sim::device::mailbox::ReplySink,
    ) {
        self.coe.poll(ctx, replies);
    }

    fn as_any(&self) -> &dyn std::any::Any {
        self
    }

    fn as_any_mut(&mut self) -> &mut dyn std::any::Any {
        self
    }
}

#[test]
fn a_slave_without_complete_access_is_read_subindex_by_subindex() {
    let rig = rig(Topology::default_segment(), MasterConfig::default());
    let dict = rig.handles[0].dictionary.clone().expect("drive dictionary");
    let refused = std::sync::Arc::new(std::sync::atomic::AtomicUsize::new(0));
    let stack = sim::device::mailbox::MailboxStack::new().with(NoCompleteAccess {
        coe: sim::device::CoeService::shared(dict.clone()),
        refused: refused.clone(),
    });
    rig.segment().slave_mut(0).unwrap().replace_device(Box::new(
        sim::device::SlaveDevice::new()
            .with_mailbox(stack)
            .with_process(sim::device::drive::Drive::new(dict.clone())),
    ));
    let report = block_on(rig.master().scan()).expect("scan");
    assert!(report.failures.is_empty(), "{:?}", report.failures);
    // 0x1C12, 0x1C13, 0x1600 and 0x1A00 were each asked for with complete access first.
    assert_eq!(refused.load(std::sync::atomic::Ordering::Relaxed), 4);
    let layout = rig
        .master()
        .process_data_layout(SlaveAddress::Position(0))
        .unwrap();
    let expected = {
        let d = lock_dictionary(&dict);
        [
            expected_pdos(&d, RX_PDO_ASSIGN, 2),
            expected_pdos(&d, TX_PDO_ASSIGN, 3),
        ]
        .concat()
    };
    assert_eq!(shape(&layout.pdos), expected);
    assert_eq!((layout.outputs_len(), layout.inputs_len()), (6, 6));
}
