//! [`CycleHook`]: code that runs on the bus thread around each cycle, next to the process
//! image: how a control program follows the cycle (in process, or through ecatd's shared
//! memory) without a lock the bus thread would wait on.

/// The image as the next frame will send it, handed to [`CycleHook::before_send`].
#[derive(Debug)]
pub struct OutgoingImage<'a> {
    /// Counts layouts: it changes whenever a scan lays the image out again (offsets may
    /// have moved; a hook must not apply outputs computed for another layout).
    pub layout: u64,
    /// Cycles completed so far (the frame being built completes the next one).
    pub cycle: u64,
    /// The whole image as it will be sent (input ranges are overwritten by the slaves).
    pub outputs: &'a mut [u8],
}

/// A completed cycle, handed to [`CycleHook::after_receive`].
#[derive(Debug)]
pub struct CompletedCycle<'a> {
    /// As in [`OutgoingImage::layout`].
    pub layout: u64,
    /// The number of this cycle (1 for the first).
    pub cycle: u64,
    /// The whole image as received.
    pub inputs: &'a [u8],
    /// The whole image as sent in this cycle.
    pub outputs: &'a [u8],
    /// The process-data working counter of the cycle.
    pub wkc: u16,
    /// The working counter it should have had.
    pub expected_wkc: u16,
}

/// Runs on the bus thread, with the image held: every call must be short and must not
/// block (copy bytes, write an eventfd, set an atomic). Installed with
/// [`Master::set_cycle_hook`](crate::master::Master::set_cycle_hook).
pub trait CycleHook: Send + Sync {
    /// Before each cyclic frame is built: may change the outputs it sends.
    fn before_send(&self, image: &mut OutgoingImage<'_>);
    /// After each cyclic frame came back, with the image it brought.
    fn after_receive(&self, cycle: &CompletedCycle<'_>);
}
