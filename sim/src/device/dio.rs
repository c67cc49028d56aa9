//! Digital I/O terminals without a mailbox (like an EL2008 / EL1008): process data only.
//!
//! Channel *n* is bit *n % 8* of byte *n / 8* of the process image, as on Beckhoff terminals.
//! The state lives behind a shared handle ([`OutputProbe`], [`InputDriver`]) because the
//! device itself is owned by the emulated ESC while a test runs: the test keeps the handle
//! to look at the "physical" outputs or to drive the inputs.

use std::sync::{Arc, Mutex, MutexGuard};

use crate::device::{Device, ProcessDataSizes};

/// Bytes needed for `channels` bits.
fn image_len(channels: u16) -> u16 {
    channels.div_ceil(8)
}

/// Locks a state mutex; a poisoned lock (a panicking test thread) still yields the bytes.
fn lock(state: &Mutex<Vec<u8>>) -> MutexGuard<'_, Vec<u8>> {
    state
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

fn bit(image: &[u8], channel: u16) -> bool {
    image
        .get(usize::from(channel / 8))
        .is_some_and(|b| b & (1 << (channel % 8)) != 0)
}

/// A digital output terminal: remembers the last outputs the master wrote.
#[derive(Debug)]
pub struct DigitalOutputs {
    channels: u16,
    state: Arc<Mutex<Vec<u8>>>,
}

/// Reads the physical output state of a [`DigitalOutputs`] from outside the segment.
#[derive(Debug, Clone)]
pub struct OutputProbe {
    channels: u16,
    state: Arc<Mutex<Vec<u8>>>,
}

impl DigitalOutputs {
    /// A terminal with `channels` outputs, all off.
    pub fn new(channels: u16) -> Self {
        DigitalOutputs {
            channels,
            state: Arc::new(Mutex::new(vec![0; usize::from(image_len(channels))])),
        }
    }

    /// Number of channels.
    pub fn channels(&self) -> u16 {
        self.channels
    }

    /// A handle that reads the outputs while the terminal sits in a segment.
    pub fn probe(&self) -> OutputProbe {
        OutputProbe {
            channels: self.channels,
            state: Arc::clone(&self.state),
        }
    }
}

impl OutputProbe {
    /// Whether output `channel` is on (false for a channel the terminal does not have).
    pub fn output(&self, channel: u16) -> bool {
        channel < self.channels && bit(&lock(&self.state), channel)
    }

    /// The last output image written by the master.
    pub fn image(&self) -> Vec<u8> {
        lock(&self.state).clone()
    }
}

impl Device for DigitalOutputs {
    fn process_data_sizes(&self) -> ProcessDataSizes {
        ProcessDataSizes {
            outputs: image_len(self.channels),
            inputs: 0,
        }
    }

    fn outputs_written(&mut self, outputs: &[u8]) {
        let mut state = lock(&self.state);
        let n = state.len().min(outputs.len());
        state[..n].copy_from_slice(&outputs[..n]);
        // Bits beyond the last channel do not exist on the terminal.
        if let Some(last) = state.last_mut() {
            let used = self.channels % 8;
            if used != 0 {
                *last &= (1u8 << used) - 1;
            }
        }
    }
}

/// A digital input terminal: reports the input state a test sets.
#[derive(Debug)]
pub struct DigitalInputs {
    channels: u16,
    state: Arc<Mutex<Vec<u8>>>,
}

/// Drives the inputs of a [`DigitalInputs`] from outside the segment.
#[derive(Debug, Clone)]
pub struct InputDriver {
    channels: u16,
    state: Arc<Mutex<Vec<u8>>>,
}

impl DigitalInputs {
    /// A terminal with `channels` inputs, all off.
    pub fn new(channels: u16) -> Self {
        DigitalInputs {
            channels,
            state: Arc::new(Mutex::new(vec![0; usize::from(image_len(channels))])),
        }
    }

    /// Number of channels.
    pub fn channels(&self) -> u16 {
        self.channels
    }

    /// A handle that sets the inputs while the terminal sits in a segment.
    pub fn driver(&self) -> InputDriver {
        InputDriver {
            channels: self.channels,
            state: Arc::clone(&self.state),
        }
    }
}

impl InputDriver {
    /// Sets input `channel`; a channel the terminal does not have is ignored.
    pub fn set_input(&self, channel: u16, on: bool) {
        if channel >= self.channels {
            return;
        }
        let mut state = lock(&self.state);
        if let Some(byte) = state.get_mut(usize::from(channel / 8)) {
            let mask = 1u8 << (channel % 8);
            if on {
                *byte |= mask;
            } else {
                *byte &= !mask;
            }
        }
    }

    /// Whether input `channel` is on.
    pub fn input(&self, channel: u16) -> bool {
        channel < self.channels && bit(&lock(&self.state), channel)
    }
}

impl Device for DigitalInputs {
    fn process_data_sizes(&self) -> ProcessDataSizes {
        ProcessDataSizes {
            outputs: 0,
            inputs: image_len(self.channels),
        }
    }

    fn read_inputs(&mut self, inputs: &mut [u8]) {
        let state = lock(&self.state);
        let n = state.len().min(inputs.len());
        inputs[..n].copy_from_slice(&state[..n]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn outputs_are_remembered_per_channel() {
        let mut terminal = DigitalOutputs::new(12);
        let probe = terminal.probe();
        assert_eq!(terminal.process_data_sizes().outputs, 2);
        terminal.outputs_written(&[0b0000_0101, 0xFF]);
        assert!(probe.output(0) && !probe.output(1) && probe.output(2));
        assert!(probe.output(11) && !probe.output(12));
        assert_eq!(probe.image(), [0b0000_0101, 0x0F]);
        terminal.outputs_written(&[]);
        assert_eq!(
            probe.image(),
            [0b0000_0101, 0x0F],
            "a short write changes nothing"
        );
    }

    #[test]
    fn inputs_follow_the_driver() {
        let mut terminal = DigitalInputs::new(8);
        let driver = terminal.driver();
        driver.set_input(3, true);
        driver.set_input(9, true);
        let mut image = [0xAAu8; 1];
        terminal.read_inputs(&mut image);
        assert_eq!(image, [0b0000_1000]);
        driver.set_input(3, false);
        terminal.read_inputs(&mut image);
        assert_eq!(image, [0]);
        assert!(!driver.input(3));
    }
}
