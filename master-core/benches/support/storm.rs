//! The SDO-upload storm of the cycle benchmarks (in-process and over veth): one thread
//! running back-to-back uploads of 0x1018:01 on every drive given, through the mailbox
//! engine that shares the bus with the cycle.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::thread::{self, JoinHandle};

use master_core::master::{Master, SlaveAddress};

/// A running storm; [`Storm::stop`] ends it and returns the uploads done.
pub struct Storm {
    stop: Arc<AtomicBool>,
    uploads: Arc<AtomicU64>,
    thread: JoinHandle<()>,
}

impl Storm {
    /// Starts uploads on the slaves at `positions` of `master`, one task each, all on one
    /// thread of their own.
    pub fn start(master: &Master, positions: impl IntoIterator<Item = u16>) -> Storm {
        let drives: Vec<_> = positions
            .into_iter()
            .map(|p| master.mailbox(SlaveAddress::Position(p)).expect("mailbox"))
            .collect();
        let stop = Arc::new(AtomicBool::new(false));
        let uploads = Arc::new(AtomicU64::new(0));
        let (task_stop, task_uploads) = (Arc::clone(&stop), Arc::clone(&uploads));
        let thread = thread::spawn(move || {
            let runtime = tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()
                .expect("runtime");
            runtime.block_on(async {
                let tasks: Vec<_> = drives
                    .into_iter()
                    .map(|drive| {
                        let stop = Arc::clone(&task_stop);
                        let uploads = Arc::clone(&task_uploads);
                        tokio::spawn(async move {
                            while !stop.load(Ordering::Relaxed) {
                                drive.sdo_upload(0x1018, 1).await.expect("upload");
                                uploads.fetch_add(1, Ordering::Relaxed);
                            }
                        })
                    })
                    .collect();
                for task in tasks {
                    task.await.expect("storm task");
                }
            });
        });
        Storm {
            stop,
            uploads,
            thread,
        }
    }

    /// Ends the storm; returns how many uploads it made.
    pub fn stop(self) -> u64 {
        self.stop.store(true, Ordering::Relaxed);
        self.thread.join().expect("storm thread");
        self.uploads.load(Ordering::Relaxed)
    }
}
