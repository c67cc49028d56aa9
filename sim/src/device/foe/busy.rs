//! The BUSY phases of an FoE write: how a simulated slave pretends to erase and program
//! flash (ETG.1000.6, spec-notes §foe, BUSY).

/// When and how long the slave answers BUSY during a write.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BusyPhase {
    /// BUSY answers before the ACK 0 of a WRQ (e.g. erasing).
    pub after_write_request: u16,
    /// BUSY answers before the ACK of the last DATA packet (e.g. programming).
    pub after_last_packet: u16,
    /// Only files whose names end with this get the phases (`None`: every file).
    pub file_suffix: Option<String>,
    /// The text sent with each BUSY.
    pub text: String,
}

impl Default for BusyPhase {
    /// No BUSY at all; when counts are set, only `*.bin` files, with the text "flashing".
    fn default() -> Self {
        BusyPhase {
            after_write_request: 0,
            after_last_packet: 0,
            file_suffix: Some(".bin".to_owned()),
            text: "flashing".to_owned(),
        }
    }
}

impl BusyPhase {
    pub(crate) fn applies(&self, name: &[u8]) -> bool {
        self.file_suffix
            .as_ref()
            .is_none_or(|suffix| name.ends_with(suffix.as_bytes()))
    }
}

/// A BUSY phase in progress: `sent` of `total` BUSY answers given.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Busy {
    pub(crate) sent: u16,
    pub(crate) total: u16,
}

impl Busy {
    pub(crate) fn new(total: u16) -> Self {
        Busy { sent: 0, total }
    }

    pub(crate) fn over(&self) -> bool {
        self.sent >= self.total
    }
}
