//! Digital I/O terminals without a mailbox (like an EL2008 / EL1008): process data only.
//!
//! Channel *n* is bit *n % 8* of byte *n / 8* of the process image, as on Beckhoff terminals.
//! The state lives behind a shared handle ([`OutputProbe`], [`InputDriver`]) because the
//! device itself is owned by the emulated ESC while a test runs: the test keeps the handle
//! to look at the "physical" outputs or to drive the inputs.
//!
//! An output terminal drives its outputs only in OP; in any other state they are in their
//! safe state, off (ETG.1000.6 §6.4.1: SAFEOP keeps outputs safe), so a slave that falls
//! back from OP, by request or through its SyncManager watchdog, switches its outputs off.
//! What the master writes meanwhile is kept and driven when OP is entered again.
//!
//! An input terminal can also be wired to an output terminal ([`DigitalInputs::wired`]), as
//! a test bench has its outputs wired back to its inputs: it then reads the output
//! terminal's shared state itself, so its inputs show what the outputs were last written
//! at the moment a frame reads them.

use std::sync::{Arc, Mutex, MutexGuard};

use ecat_wire::register::al::AlState;
use ecat_wire::register::al_status_code::AlStatusCode;

use crate::device::{Device, DeviceContext, ProcessDataSizes};

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

/// A digital output terminal: drives the last outputs the master wrote while in OP.
#[derive(Debug)]
pub struct DigitalOutputs {
    channels: u16,
    /// The physical outputs (what a probe and a wired input terminal see).
    state: Arc<Mutex<Vec<u8>>>,
    /// The last complete output image written by the master, whatever the state.
    written: Vec<u8>,
    /// Whether the terminal is in OP (outputs driven) rather than in their safe state.
    operational: bool,
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
        let len = usize::from(image_len(channels));
        DigitalOutputs {
            channels,
            state: Arc::new(Mutex::new(vec![0; len])),
            written: vec![0; len],
            operational: false,
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
        let n = self.written.len().min(outputs.len());
        self.written[..n].copy_from_slice(&outputs[..n]);
        // Bits beyond the last channel do not exist on the terminal.
        if let Some(last) = self.written.last_mut() {
            let used = self.channels % 8;
            if used != 0 {
                *last &= (1u8 << used) - 1;
            }
        }
        if self.operational {
            lock(&self.state).copy_from_slice(&self.written);
        }
    }

    fn state_change(
        &mut self,
        _from: AlState,
        to: AlState,
        _ctx: &DeviceContext,
    ) -> Result<(), AlStatusCode> {
        self.operational = to == AlState::Op;
        let mut state = lock(&self.state);
        if self.operational {
            state.copy_from_slice(&self.written);
        } else {
            state.fill(0);
        }
        Ok(())
    }
}

/// A digital input terminal: reports the input state a test sets and, when wired to a
/// [`DigitalOutputs`] terminal (as on a test bench whose outputs are wired back to its
/// inputs), that terminal's outputs.
///
/// On a wired terminal the wire and the [`InputDriver`] act in parallel, like a 24 V input
/// fed both by an output and by a switch: input *n* is on when output *n* or the driver
/// says so. The driver therefore still turns inputs on, but cannot turn off an input whose
/// output is on. This keeps every test that drives inputs working on a wired segment, as
/// long as it leaves the wired outputs off.
#[derive(Debug)]
pub struct DigitalInputs {
    inputs: InputState,
}

/// Drives the inputs of a [`DigitalInputs`] from outside the segment.
#[derive(Debug, Clone)]
pub struct InputDriver {
    inputs: InputState,
}

/// What a [`DigitalInputs`] and its [`InputDriver`]s share.
#[derive(Debug, Clone)]
struct InputState {
    channels: u16,
    /// The inputs set through the driver.
    driven: Arc<Mutex<Vec<u8>>>,
    /// The output state of the terminal wired to these inputs: the very `Arc` the
    /// [`DigitalOutputs`] writes, so the inputs follow its outputs without any copy step
    /// that could lag a frame behind.
    wire: Option<Arc<Mutex<Vec<u8>>>>,
}

impl InputState {
    /// The bits of image byte `index` that are channels of this terminal (a wider output
    /// terminal's extra outputs go nowhere).
    fn mask(&self, index: usize) -> u8 {
        match usize::from(self.channels).saturating_sub(index * 8) {
            0 => 0,
            n if n >= 8 => 0xFF,
            n => (1u8 << n) - 1,
        }
    }

    /// Writes the input image into `out` (as much of it as fits): the driven bits or'ed
    /// with the wired ones. Runs as every frame passes, so it neither allocates nor holds
    /// two locks at once.
    fn fill(&self, out: &mut [u8]) {
        let n = {
            let driven = lock(&self.driven);
            let n = driven.len().min(out.len());
            out[..n].copy_from_slice(&driven[..n]);
            n
        };
        if let Some(wire) = &self.wire {
            let wire = lock(wire);
            for (index, (out, wired)) in out[..n].iter_mut().zip(wire.iter()).enumerate() {
                *out |= wired & self.mask(index);
            }
        }
    }

    fn input(&self, channel: u16) -> bool {
        if channel >= self.channels {
            return false;
        }
        let driven = bit(&lock(&self.driven), channel);
        driven || self.wire.as_ref().is_some_and(|w| bit(&lock(w), channel))
    }
}

impl DigitalInputs {
    /// A terminal with `channels` inputs, all off.
    pub fn new(channels: u16) -> Self {
        DigitalInputs {
            inputs: InputState {
                channels,
                driven: Arc::new(Mutex::new(vec![0; usize::from(image_len(channels))])),
                wire: None,
            },
        }
    }

    /// A terminal with `channels` inputs wired to the outputs `outputs` reads: input *n*
    /// follows output *n* (see the type's documentation for the driver on top). Channels
    /// beyond the output terminal's have no wire and stay with the driver.
    pub fn wired(channels: u16, outputs: &OutputProbe) -> Self {
        let mut terminal = DigitalInputs::new(channels);
        terminal.inputs.wire = Some(Arc::clone(&outputs.state));
        terminal
    }

    /// Number of channels.
    pub fn channels(&self) -> u16 {
        self.inputs.channels
    }

    /// Whether the inputs are wired to an output terminal.
    pub fn is_wired(&self) -> bool {
        self.inputs.wire.is_some()
    }

    /// A handle that sets the inputs while the terminal sits in a segment.
    pub fn driver(&self) -> InputDriver {
        InputDriver {
            inputs: self.inputs.clone(),
        }
    }
}

impl InputDriver {
    /// Sets input `channel` as a switch would; a channel the terminal does not have is
    /// ignored. On a wired terminal the switch sits in parallel with the wire: switching
    /// it off leaves the input on while its output is on.
    pub fn set_input(&self, channel: u16, on: bool) {
        if channel >= self.inputs.channels {
            return;
        }
        let mut state = lock(&self.inputs.driven);
        if let Some(byte) = state.get_mut(usize::from(channel / 8)) {
            let mask = 1u8 << (channel % 8);
            if on {
                *byte |= mask;
            } else {
                *byte &= !mask;
            }
        }
    }

    /// Whether input `channel` is on, as the terminal reports it: driven on, or (on a
    /// wired terminal) its output on.
    pub fn input(&self, channel: u16) -> bool {
        self.inputs.input(channel)
    }

    /// Whether the terminal's inputs are wired to an output terminal.
    pub fn is_wired(&self) -> bool {
        self.inputs.wire.is_some()
    }
}

impl Device for DigitalInputs {
    fn process_data_sizes(&self) -> ProcessDataSizes {
        ProcessDataSizes {
            outputs: 0,
            inputs: image_len(self.inputs.channels),
        }
    }

    fn read_inputs(&mut self, inputs: &mut [u8]) {
        self.inputs.fill(inputs);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// What the ESC tells a terminal without a mailbox in SAFEOP.
    fn ctx() -> DeviceContext {
        DeviceContext {
            station_address: 0x1001,
            al_state: AlState::SafeOp,
            rx_mailbox_size: 0,
            tx_mailbox_size: 0,
        }
    }

    /// An output terminal of `channels` outputs, in OP.
    fn operational(channels: u16) -> DigitalOutputs {
        let mut terminal = DigitalOutputs::new(channels);
        terminal
            .state_change(AlState::SafeOp, AlState::Op, &ctx())
            .unwrap();
        terminal
    }

    #[test]
    fn outputs_are_remembered_per_channel() {
        let mut terminal = operational(12);
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
        assert!(!terminal.is_wired() && !driver.is_wired());
    }

    #[test]
    fn wired_inputs_follow_the_outputs_with_the_driver_in_parallel() {
        let mut outputs = operational(8);
        let mut inputs = DigitalInputs::wired(8, &outputs.probe());
        let driver = inputs.driver();
        assert!(inputs.is_wired() && driver.is_wired());
        let mut image = [0u8; 1];
        outputs.outputs_written(&[0b1010_0101]);
        inputs.read_inputs(&mut image);
        assert_eq!(image, [0b1010_0101], "the wire, as soon as written");
        assert!(driver.input(0) && !driver.input(1));
        // The driver adds inputs; it cannot take away one whose output is on.
        driver.set_input(1, true);
        driver.set_input(0, false);
        inputs.read_inputs(&mut image);
        assert_eq!(image, [0b1010_0111]);
        assert!(driver.input(0) && driver.input(1));
        outputs.outputs_written(&[0]);
        inputs.read_inputs(&mut image);
        assert_eq!(image, [0b0000_0010], "the driven input only");
        assert!(!driver.input(0));
    }

    #[test]
    fn a_narrower_input_terminal_takes_only_its_channels_from_the_wire() {
        let mut outputs = operational(16);
        let mut inputs = DigitalInputs::wired(4, &outputs.probe());
        assert_eq!(inputs.process_data_sizes().inputs, 1);
        outputs.outputs_written(&[0xFF, 0xFF]);
        let mut image = [0u8; 1];
        inputs.read_inputs(&mut image);
        assert_eq!(image, [0x0F]);
        assert!(!inputs.driver().input(4));
    }

    #[test]
    fn outputs_are_off_outside_op_and_come_back_with_it() {
        let mut terminal = DigitalOutputs::new(8);
        let probe = terminal.probe();
        let ctx = ctx();
        terminal.outputs_written(&[0x5A]);
        assert_eq!(probe.image(), [0], "SAFEOP: written, not driven");
        terminal
            .state_change(AlState::SafeOp, AlState::Op, &ctx)
            .unwrap();
        assert_eq!(probe.image(), [0x5A], "OP drives what was written");
        terminal.outputs_written(&[0x81]);
        assert_eq!(probe.image(), [0x81]);
        terminal
            .state_change(AlState::Op, AlState::SafeOp, &ctx)
            .unwrap();
        assert_eq!(probe.image(), [0], "back in SAFEOP: the safe state");
        terminal.outputs_written(&[0xFF]);
        assert_eq!(probe.image(), [0]);
    }
}
