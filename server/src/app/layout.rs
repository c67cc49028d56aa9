//! The application interface's view of the master's layout: every mapped entry with its
//! place in the image, and the safe image (`[[app.safe_output]]` values, zero elsewhere).

use ecat_app::entry::{Direction, Entry};
use master_core::master::{Master, SlaveAddress};

/// The safe value of one output entry, its slave resolved from the configuration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SafeValue {
    /// The slave.
    pub address: SlaveAddress,
    /// Object index.
    pub index: u16,
    /// Subindex.
    pub subindex: u8,
    /// The value.
    pub value: i64,
}

/// Every mapped entry of every slave, slave by slave in ring order (outputs first, as the
/// master lists them), and the image's length.
pub fn entries(master: &Master) -> (Vec<Entry>, usize) {
    let image_len = master.cycle_stats().image_len;
    let mut entries = Vec::new();
    for slave in master.slaves() {
        let Ok(mapped) = master.entries(SlaveAddress::Position(slave.position)) else {
            continue;
        };
        entries.extend(mapped.into_iter().map(|e| Entry {
            position: e.position,
            station: slave.station,
            pdo: e.pdo,
            index: e.index,
            subindex: e.subindex,
            direction: if e.output {
                Direction::Out
            } else {
                Direction::In
            },
            data_type: e.data_type.map_or(0, u16::from),
            bit_offset: e.bit_offset,
            bit_length: u16::from(e.bit_length),
            name: e.name,
        }));
    }
    (entries, image_len)
}

/// The safe outputs: zero, but for the configured values of the entries the layout maps
/// (a value for an entry it does not map, or that does not fit, is logged and left out).
pub fn safe_image(
    master: &Master,
    entries: &[Entry],
    image_len: usize,
    safe: &[SafeValue],
) -> Vec<u8> {
    let mut image = vec![0; image_len];
    for value in safe {
        let position = master
            .entries(value.address)
            .ok()
            .and_then(|mapped| mapped.first().map(|e| e.position));
        let entry = entries.iter().find(|e| {
            Some(e.position) == position
                && e.index == value.index
                && e.subindex == value.subindex
                && e.direction == Direction::Out
        });
        match entry {
            Some(entry) if entry.accepts(value.value) => {
                entry.set(&mut image, value.value as u64);
            }
            Some(_) => tracing::warn!(
                index = value.index,
                subindex = value.subindex,
                value = value.value,
                "[[app.safe_output]]: the value does not fit the entry; its safe value is 0"
            ),
            None => tracing::warn!(
                slave = ?value.address,
                index = value.index,
                subindex = value.subindex,
                "[[app.safe_output]]: the segment maps no such output entry"
            ),
        }
    }
    image
}
