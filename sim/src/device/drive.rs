//! A CiA-402-like drive whose process data are laid out by its own object dictionary.
//!
//! The process image is what the dictionary says (spec-notes §coe.pdo): SM2 carries the RxPDOs
//! listed in 0x1C12, SM3 the TxPDOs listed in 0x1C13, each PDO the entries its mapping
//! object (0x16xx / 0x1Axx) lists, packed bit by bit in order; an entry with index 0 is a
//! gap. So a master that rewrites the assignment or a mapping in PREOP changes
//! [`Device::process_data_sizes`] and which objects [`Device::outputs_written`] writes and
//! [`Device::read_inputs`] reads.
//!
//! The behaviour is the smallest that makes a master's bring-up observable:
//! - the statusword 0x6041 follows the controlword 0x6040 through the CiA 402 power states
//!   (switch on disabled → ready to switch on → switched on → operation enabled, one step per
//!   output update; "disable voltage" and "quick stop" go back to switch on disabled; a fault
//!   is left with a fault-reset edge);
//! - while operation is enabled the actual position 0x6064 takes the target position 0x607A
//!   (an ideal axis).

use ecat_od::standard::{RX_PDO_ASSIGN, TX_PDO_ASSIGN};
use ecat_od::{PdoEntry, StaticDictionary};

use crate::device::coe::{SharedDictionary, lock_dictionary};
use crate::device::{Device, ProcessDataSizes};

/// 0x6040 Controlword.
pub const CONTROLWORD: u16 = 0x6040;
/// 0x6041 Statusword.
pub const STATUSWORD: u16 = 0x6041;
/// 0x607A Target position.
pub const TARGET_POSITION: u16 = 0x607A;
/// 0x6064 Position actual value.
pub const ACTUAL_POSITION: u16 = 0x6064;

/// The CiA 402 power states the drive goes through.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PowerState {
    /// Switch on disabled (statusword 0x0040).
    SwitchOnDisabled,
    /// Ready to switch on (0x0021).
    ReadyToSwitchOn,
    /// Switched on (0x0023).
    SwitchedOn,
    /// Operation enabled (0x0027).
    OperationEnabled,
    /// Fault (0x0008).
    Fault,
}

impl PowerState {
    /// The statusword bits 0-6 of the state (bit 4 "voltage enabled" set while powered).
    pub fn statusword(self) -> u16 {
        match self {
            PowerState::SwitchOnDisabled => 0x0040,
            PowerState::ReadyToSwitchOn => 0x0031,
            PowerState::SwitchedOn => 0x0033,
            PowerState::OperationEnabled => 0x0037,
            PowerState::Fault => 0x0008,
        }
    }

    /// The next state for `controlword` (one transition at most); `reset_edge` is a rising
    /// edge of bit 7 (fault reset).
    pub fn next(self, controlword: u16, reset_edge: bool) -> PowerState {
        use PowerState::*;
        if self == Fault {
            return if reset_edge { SwitchOnDisabled } else { Fault };
        }
        let disable_voltage = controlword & 0x0002 == 0;
        let quick_stop = controlword & 0x0006 == 0x0002;
        let shutdown = controlword & 0x0087 == 0x0006;
        let switch_on = controlword & 0x008F == 0x0007;
        let enable = controlword & 0x008F == 0x000F;
        if disable_voltage || quick_stop {
            return SwitchOnDisabled;
        }
        match self {
            SwitchOnDisabled if shutdown => ReadyToSwitchOn,
            ReadyToSwitchOn if switch_on || enable => SwitchedOn,
            SwitchedOn if enable => OperationEnabled,
            SwitchedOn | OperationEnabled if shutdown => ReadyToSwitchOn,
            OperationEnabled if switch_on => SwitchedOn,
            other => other,
        }
    }
}

/// The drive: dictionary-mapped process data and a CiA-402-like power state machine.
#[derive(Debug)]
pub struct Drive {
    dict: SharedDictionary,
    state: PowerState,
    last_controlword: u16,
}

impl Drive {
    /// A drive over `dict` (shared with its [`crate::device::coe::CoeService`]), switch on
    /// disabled. The dictionary should hold 0x6040, 0x6041, 0x607A, 0x6064, the mapping
    /// objects and 0x1C12/0x1C13; missing objects are simply not exchanged.
    pub fn new(dict: SharedDictionary) -> Self {
        let drive = Drive {
            dict,
            state: PowerState::SwitchOnDisabled,
            last_controlword: 0,
        };
        drive.publish_status();
        drive
    }

    /// The current power state.
    pub fn power_state(&self) -> PowerState {
        self.state
    }

    /// Puts the drive into FAULT (a fault reset edge on bit 7 of the controlword clears it).
    pub fn set_fault(&mut self) {
        self.state = PowerState::Fault;
        self.publish_status();
    }

    fn publish_status(&self) {
        let mut dict = lock_dictionary(&self.dict);
        let _ = dict.set(STATUSWORD, 0, &self.state.statusword());
    }

    /// Applies the controlword and target position the master wrote.
    fn step(&mut self) {
        let mut dict = lock_dictionary(&self.dict);
        let controlword = dict.get::<u16>(CONTROLWORD, 0).unwrap_or(0);
        let reset_edge = controlword & 0x0080 != 0 && self.last_controlword & 0x0080 == 0;
        self.last_controlword = controlword;
        self.state = self.state.next(controlword, reset_edge);
        let _ = dict.set(STATUSWORD, 0, &self.state.statusword());
        if self.state == PowerState::OperationEnabled
            && let Ok(target) = dict.get::<i32>(TARGET_POSITION, 0)
        {
            let _ = dict.set(ACTUAL_POSITION, 0, &target);
        }
    }
}

/// The entries of every PDO assigned by `assign_index`, in image order.
fn image_entries(dict: &StaticDictionary, assign_index: u16) -> Vec<PdoEntry> {
    dict.assigned_pdos(assign_index)
        .into_iter()
        .flat_map(|pdo| dict.mapped_entries(pdo))
        .collect()
}

fn bytes_for(bits: u32) -> u16 {
    u16::try_from(bits.div_ceil(8)).unwrap_or(u16::MAX)
}

fn get_bit(bytes: &[u8], bit: usize) -> bool {
    bytes
        .get(bit / 8)
        .is_some_and(|b| b & (1 << (bit % 8)) != 0)
}

fn set_bit(bytes: &mut [u8], bit: usize, on: bool) {
    if let Some(b) = bytes.get_mut(bit / 8) {
        if on {
            *b |= 1 << (bit % 8);
        } else {
            *b &= !(1 << (bit % 8));
        }
    }
}

/// Copies `len` bits from `src` at bit `from` to `dst` at bit `to` (out-of-range bits are
/// skipped: a short SM buffer simply carries less).
fn copy_bits(src: &[u8], from: usize, dst: &mut [u8], to: usize, len: usize) {
    for i in 0..len {
        set_bit(dst, to + i, get_bit(src, from + i));
    }
}

impl Device for Drive {
    fn process_data_sizes(&self) -> ProcessDataSizes {
        let dict = lock_dictionary(&self.dict);
        ProcessDataSizes {
            outputs: bytes_for(dict.process_data_bits(RX_PDO_ASSIGN)),
            inputs: bytes_for(dict.process_data_bits(TX_PDO_ASSIGN)),
        }
    }

    fn outputs_written(&mut self, outputs: &[u8]) {
        {
            let mut dict = lock_dictionary(&self.dict);
            let mut at = 0usize;
            for entry in image_entries(&dict, RX_PDO_ASSIGN) {
                let bits = usize::from(entry.bit_length);
                if entry.index != 0
                    && let Some(value) = dict
                        .get_object_mut(entry.index)
                        .and_then(|o| o.entry_mut(entry.subindex).ok())
                        .map(|e| &mut e.value)
                {
                    copy_bits(outputs, at, value, 0, bits);
                }
                at += bits;
            }
        }
        self.step();
    }

    fn read_inputs(&mut self, inputs: &mut [u8]) {
        let dict = lock_dictionary(&self.dict);
        let mut at = 0usize;
        for entry in image_entries(&dict, TX_PDO_ASSIGN) {
            let bits = usize::from(entry.bit_length);
            if entry.index != 0
                && let Ok(value) = dict.get_bytes(entry.index, entry.subindex)
            {
                copy_bits(value, 0, inputs, at, bits);
            }
            at += bits;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn power_states_follow_the_controlword() {
        let s = PowerState::SwitchOnDisabled;
        let s = s.next(0x0006, false);
        assert_eq!(s, PowerState::ReadyToSwitchOn);
        let s = s.next(0x000F, false);
        assert_eq!(s, PowerState::SwitchedOn);
        let s = s.next(0x000F, false);
        assert_eq!(s, PowerState::OperationEnabled);
        assert_eq!(s.statusword() & 0x006F, 0x0027);
        assert_eq!(s.next(0x0000, false), PowerState::SwitchOnDisabled);
        assert_eq!(
            PowerState::Fault.next(0x0080, true),
            PowerState::SwitchOnDisabled
        );
        assert_eq!(PowerState::Fault.next(0x0080, false), PowerState::Fault);
    }

    #[test]
    fn bits_copy_across_byte_boundaries() {
        let src = [0b1011_0000, 0b0000_0001];
        let mut dst = [0u8; 1];
        copy_bits(&src, 4, &mut dst, 0, 5);
        assert_eq!(dst[0], 0b0001_1011);
    }
}
