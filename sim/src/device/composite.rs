//! [`SlaveDevice`]: a whole slave application made of parts, as most real slaves are: an
//! optional mailbox ([`MailboxStack`] with its protocols) and an optional process-data
//! application (digital I/O, a drive).
//!
//! Mailbox calls go to the stack, process-data calls to the application; a state change is
//! offered to both (mailbox first, so a fall back to INIT resets the mailbox even when the
//! application refuses nothing).

use ecat_wire::register::al::AlState;
use ecat_wire::register::al_status_code::AlStatusCode;

use crate::device::{Device, DeviceContext, MailboxStack, Outbox, ProcessDataSizes};

/// A slave application: mailbox stack and process-data application, each optional.
#[derive(Default)]
pub struct SlaveDevice {
    mailbox: Option<MailboxStack>,
    process: Option<Box<dyn Device>>,
}

impl std::fmt::Debug for SlaveDevice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SlaveDevice")
            .field("mailbox", &self.mailbox)
            .field("process", &self.process.is_some())
            .finish()
    }
}

impl SlaveDevice {
    /// A slave with neither mailbox nor process data.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds (or replaces) the mailbox stack.
    pub fn with_mailbox(mut self, stack: MailboxStack) -> Self {
        self.mailbox = Some(stack);
        self
    }

    /// Adds (or replaces) the process-data application.
    pub fn with_process(mut self, app: impl Device + 'static) -> Self {
        self.process = Some(Box::new(app));
        self
    }

    /// The mailbox stack, if the slave has one.
    pub fn mailbox(&self) -> Option<&MailboxStack> {
        self.mailbox.as_ref()
    }

    /// The mailbox stack, mutably (e.g. to raise an emergency through its CoE service).
    pub fn mailbox_mut(&mut self) -> Option<&mut MailboxStack> {
        self.mailbox.as_mut()
    }

    /// The process-data application, if any.
    pub fn process(&self) -> Option<&dyn Device> {
        self.process.as_deref()
    }
}

impl Device for SlaveDevice {
    fn mailbox_received(&mut self, message: &[u8], ctx: &DeviceContext, outbox: &mut Outbox) {
        if let Some(stack) = &mut self.mailbox {
            stack.mailbox_received(message, ctx, outbox);
        }
    }

    fn poll(&mut self, ctx: &DeviceContext, outbox: &mut Outbox) {
        if let Some(stack) = &mut self.mailbox {
            stack.poll(ctx, outbox);
        }
        if let Some(app) = &mut self.process {
            app.poll(ctx, outbox);
        }
    }

    fn process_data_sizes(&self) -> ProcessDataSizes {
        self.process
            .as_ref()
            .map(|app| app.process_data_sizes())
            .unwrap_or_default()
    }

    fn outputs_written(&mut self, outputs: &[u8]) {
        if let Some(app) = &mut self.process {
            app.outputs_written(outputs);
        }
    }

    fn read_inputs(&mut self, inputs: &mut [u8]) {
        if let Some(app) = &mut self.process {
            app.read_inputs(inputs);
        }
    }

    fn state_change(
        &mut self,
        from: AlState,
        to: AlState,
        ctx: &DeviceContext,
    ) -> Result<(), AlStatusCode> {
        if let Some(stack) = &mut self.mailbox {
            stack.state_change(from, to, ctx)?;
        }
        if let Some(app) = &mut self.process {
            app.state_change(from, to, ctx)?;
        }
        Ok(())
    }
}
