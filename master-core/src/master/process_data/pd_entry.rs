//! Named entries of the process image: where each mapped object of each slave sits (bit
//! offset and length in the image), and snapshots of the image taken at one cycle.

use crate::wire::coe::DataType;
use crate::wire::sii::SiiImage;

use super::bits::copy_bits;
use crate::master::record::SlaveRecord;

/// One mapped object in the process image.
///
/// Offsets hold until the next scan (which lays the image out again).
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct PdEntry {
    /// Ring position of the slave.
    pub position: u16,
    /// The PDO that maps it.
    pub pdo: u16,
    /// Object index.
    pub index: u16,
    /// Object subindex.
    pub subindex: u8,
    /// The entry's name from the SII (empty if the SII does not name it).
    pub name: String,
    /// Data type, when known.
    pub data_type: Option<DataType>,
    /// First bit in the process image (bit 0 = LSB of image byte 0).
    pub bit_offset: u32,
    /// Bits it takes.
    pub bit_length: u8,
    /// True for an output (master → slave), false for an input.
    pub output: bool,
}

impl PdEntry {
    /// Bytes a value of this entry takes (its bits rounded up).
    pub fn byte_len(&self) -> usize {
        usize::from(self.bit_length).div_ceil(8)
    }
}

/// The mapped entries (gaps left out) of the slave of `record`, in image order.
pub(crate) fn entries_of(record: &SlaveRecord) -> Vec<PdEntry> {
    let sii = SiiImage::parse(&record.sii).ok();
    let pd = record.info.process_data;
    let mut entries = Vec::new();
    for output in [true, false] {
        let mut sm_start = 8 * u64::from(if output {
            pd.outputs_offset
        } else {
            pd.inputs_offset
        });
        for sm in record
            .layout
            .sync_managers
            .iter()
            .filter(|sm| sm.outputs == output)
        {
            let mut at = sm_start;
            for pdo in record
                .layout
                .pdos
                .iter()
                .filter(|p| p.sync_manager == sm.index)
            {
                for e in &pdo.entries {
                    if e.index != 0 {
                        entries.push(PdEntry {
                            position: record.info.position,
                            pdo: pdo.index,
                            index: e.index,
                            subindex: e.subindex,
                            name: sii
                                .as_ref()
                                .map(|s| sii_name(s, e.index, e.subindex))
                                .unwrap_or_default(),
                            data_type: e.data_type,
                            bit_offset: u32::try_from(at).unwrap_or(u32::MAX),
                            bit_length: e.bit_length,
                            output,
                        });
                    }
                    at += u64::from(e.bit_length);
                }
            }
            sm_start += 8 * u64::from(sm.length);
        }
    }
    entries
}

/// The name the SII's PDO categories give `index:subindex`.
fn sii_name(sii: &SiiImage<'_>, index: u16, subindex: u8) -> String {
    sii.rxpdo
        .iter()
        .chain(sii.txpdo.iter())
        .flat_map(|p| p.entries.iter())
        .find(|e| e.index == index && e.subindex == subindex)
        .and_then(|e| sii.string(e.name_idx))
        .unwrap_or_default()
        .to_owned()
}

/// The process image as one cycle left it: the inputs that cycle brought, the outputs as
/// they stood. Reuse one with [`Master::snapshot_into`](crate::master::Master::snapshot_into) to
/// avoid allocating every cycle.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ImageSnapshot {
    /// Cycles completed when the snapshot was taken (the inputs are from this one).
    pub cycle: u64,
    /// Working counter of that cycle's process-data datagram.
    pub wkc: u16,
    /// The working counter it should have had.
    pub expected_wkc: u16,
    /// The whole image as received.
    pub inputs: Vec<u8>,
    /// The whole image as sent next.
    pub outputs: Vec<u8>,
}

impl ImageSnapshot {
    /// The value of `entry` (inputs from the received image, outputs from the sent one),
    /// little-endian, `entry.byte_len()` bytes; `None` if it lies outside the image.
    pub fn get(&self, entry: &PdEntry) -> Option<Vec<u8>> {
        let mut value = vec![0u8; entry.byte_len()];
        let source = if entry.output {
            &self.outputs
        } else {
            &self.inputs
        };
        copy_bits(
            source,
            entry.bit_offset as usize,
            &mut value,
            0,
            usize::from(entry.bit_length),
        )
        .then_some(value)
    }

    /// The value of an entry of at most 64 bits as an unsigned number.
    pub fn get_u64(&self, entry: &PdEntry) -> Option<u64> {
        let bytes = self.get(entry)?;
        if bytes.len() > 8 {
            return None;
        }
        Some(
            bytes
                .iter()
                .rev()
                .fold(0u64, |acc, &b| (acc << 8) | u64::from(b)),
        )
    }

    /// The value of a one-bit entry.
    pub fn get_bool(&self, entry: &PdEntry) -> Option<bool> {
        self.get_u64(entry).map(|v| v != 0)
    }

    /// Whether the cycle's working counter was the expected one (all slaves exchanged).
    pub fn complete(&self) -> bool {
        self.wkc == self.expected_wkc
    }
}
