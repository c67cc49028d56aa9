//! What ecatd `--simulate` can do to its own simulated slaves beyond EtherCAT: raise a CoE
//! emergency on demand (for end-to-end tests of the event stream and for demonstrations),
//! and read a digital output terminal's physical outputs (what reached the wire's far end).
//! Only ever built from the in-process simulator; a real segment has none. Without the
//! `simulate` feature there is no simulator and [`SimHooks`] has no value at all.

#[cfg(feature = "simulate")]
pub use hooks::SimHooks;
#[cfg(not(feature = "simulate"))]
pub use none::SimHooks;

#[cfg(feature = "simulate")]
mod hooks {
    use sim::device::coe::EmergencyTrigger;
    use sim::device::dio::OutputProbe;
    use sim::topology::SlaveHandles;

    use crate::error::ApiError;

    /// Hooks into the simulated slaves, by ring position.
    #[derive(Debug, Clone, Default)]
    pub struct SimHooks {
        emergencies: Vec<Option<EmergencyTrigger>>,
        outputs: Vec<Option<OutputProbe>>,
    }

    impl SimHooks {
        /// The hooks of a built simulator, from its per-slave handles (ring order).
        pub fn new(slaves: &[SlaveHandles]) -> SimHooks {
            SimHooks {
                emergencies: slaves.iter().map(|h| h.emergencies.clone()).collect(),
                outputs: slaves.iter().map(|h| h.outputs.clone()).collect(),
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
    }
}
