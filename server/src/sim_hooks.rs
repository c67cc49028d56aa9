//! What ecatd `--simulate` can do to its own simulated slaves beyond EtherCAT: raise a CoE
//! emergency on demand (for end-to-end tests of the event stream and for demonstrations),
//! read a digital output terminal's physical outputs (what reached the wire's far end), and
//! on a ring (`--ring`) cut a cable, kill a slave or heal them all ([`RingCut`]).
//! Only ever built from the in-process simulator; a real segment has none. Without the
//! `simulate` feature there is no simulator and [`SimHooks`] has no value at all.

#[cfg(feature = "simulate")]
pub use hooks::SimHooks;

/// What to do to a simulated ring (`POST /api/v1/sim/ring`): the cut happens between two
/// frames (the link locks the segment per frame), as a cable pulled on a running bus.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RingCut {
    /// Cut a cable: 0 is the master's primary cable, `k` the cable after `k` slaves, the
    /// slave count the last slave's cable back into the backup port.
    Break {
        /// The cable.
        cable: u16,
    },
    /// Switch the slave at this ring position off (it neither processes nor forwards).
    Kill {
        /// The ring position.
        position: u16,
    },
    /// Reconnect every cable and power every slave again.
    Heal,
}
#[cfg(not(feature = "simulate"))]
pub use none::SimHooks;

#[cfg(feature = "simulate")]
mod hooks {
    use sim::device::coe::EmergencyTrigger;
    use sim::device::dio::OutputProbe;
    use sim::link::SharedSegment;
    use sim::topology::SlaveHandles;

    use super::RingCut;
    use crate::error::ApiError;

    /// Hooks into the simulated slaves, by ring position.
    #[derive(Debug, Clone, Default)]
    pub struct SimHooks {
        emergencies: Vec<Option<EmergencyTrigger>>,
        outputs: Vec<Option<OutputProbe>>,
        /// The segment, when it runs as a ring (the cuts are for rings only).
        ring: Option<SharedSegment>,
    }

    impl SimHooks {
        /// The hooks of a built simulator, from its per-slave handles (ring order).
        pub fn new(slaves: &[SlaveHandles]) -> SimHooks {
            SimHooks {
                emergencies: slaves.iter().map(|h| h.emergencies.clone()).collect(),
                outputs: slaves.iter().map(|h| h.outputs.clone()).collect(),
                ring: None,
            }
        }

        /// The segment runs as a ring: [`SimHooks::ring`] may cut it.
        pub fn set_ring(&mut self, segment: SharedSegment) {
            self.ring = Some(segment);
        }

        /// Cuts a cable, kills a slave or heals the ring. Refused (and nothing changed)
        /// on a segment that is no ring, or for a cable or position that does not exist.
        pub fn ring(&self, cut: RingCut) -> Result<(), ApiError> {
            let segment = self.ring.as_ref().ok_or_else(|| {
                ApiError::not_a_ring(
                    "the simulated segment is a line, not a ring: start ecatd with \
                     --simulate --ring (or a topology with ring = true)",
                )
            })?;
            // Held for the cut only, never across an await: the bus thread takes the same
            // lock for every frame, so the cut falls between two frames.
            let mut segment = segment
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner);
            match cut {
                RingCut::Break { cable } => segment
                    .break_cable(usize::from(cable))
                    .map_err(|err| ApiError::invalid_field("cable", err)),
                RingCut::Kill { position } => segment
                    .kill(usize::from(position))
                    .map_err(|err| ApiError::invalid_field("position", err)),
                RingCut::Heal => {
                    segment.heal();
                    Ok(())
                }
            }
        }

        /// The physical outputs of the simulated digital output terminal at `position`,
        /// as the last frame left them (what a probe on its terminals would measure).
        pub fn outputs(&self, position: u16) -> Result<Vec<u8>, ApiError> {
            self.outputs
                .get(usize::from(position))
                .and_then(Option::as_ref)
                .map(OutputProbe::image)
                .ok_or_else(|| {
                    ApiError::invalid(format!(
                        "simulated slave {position} is not a digital output terminal"
                    ))
                })
        }

        /// Queues a CoE emergency on the simulated slave at `position`; the master reads it at
        /// its next poll of the slave's mailbox.
        pub fn raise_emergency(
            &self,
            position: u16,
            error_code: u16,
            error_register: u8,
            data: [u8; 5],
        ) -> Result<(), ApiError> {
            let trigger = self
                .emergencies
                .get(usize::from(position))
                .and_then(Option::as_ref)
                .ok_or_else(|| {
                    ApiError::invalid(format!(
                        "simulated slave {position} has no CoE mailbox to raise emergencies on"
                    ))
                })?;
            if trigger.raise(error_code, error_register, data) {
                Ok(())
            } else {
                Err(ApiError::too_large(format!(
                    "simulated slave {position}: emergency queue full"
                )))
            }
        }
    }
}

#[cfg(not(feature = "simulate"))]
mod none {
    use super::RingCut;
    use crate::error::ApiError;

    /// Hooks into simulated slaves: none exist in an ecatd built without the simulator.
    #[derive(Debug, Clone)]
    pub enum SimHooks {}

    impl SimHooks {
        /// Never called: there is no value to call it on.
        pub fn raise_emergency(
            &self,
            _position: u16,
            _error_code: u16,
            _error_register: u8,
            _data: [u8; 5],
        ) -> Result<(), ApiError> {
            match *self {}
        }

        /// Never called: there is no value to call it on.
        pub fn outputs(&self, _position: u16) -> Result<Vec<u8>, ApiError> {
            match *self {}
        }

        /// Never called: there is no value to call it on.
        pub fn ring(&self, _cut: RingCut) -> Result<(), ApiError> {
            match *self {}
        }
    }
}
