//! Several objects on one frame stream, each with a [`StreamTracker`] (a population) of
//! its own. Tracking frames run on the caller's thread, one object after the other. With
//! more than one object, an object that must be (re)acquired is searched on a thread of
//! its own, so the others go on being tracked on every frame meanwhile; it rejoins
//! when its search is done. One acquisition runs at a time, with all fitness workers:
//! two at once would each take twice as long, and an acquisition's answer is only as
//! good as it is fresh.

use std::thread::JoinHandle;

use crate::estimator::tracking::{Estimate, FrameError, StreamTracker};
use crate::vision::lookup::SbsBytes;

/// What one object gave on a frame.
#[derive(Debug, Clone, Copy)]
pub enum Outcome {
    /// Its estimate on this frame.
    Estimate(Estimate),
    /// It is being acquired in the background: no estimate on this frame.
    Acquiring,
}

/// Where an object's tracker is.
enum Slot {
    /// Ready for the next frame.
    Here(Box<StreamTracker>),
    /// Acquiring on its own thread; the thread hands the tracker back.
    Away(JoinHandle<Box<StreamTracker>>),
    /// Its acquisition thread died (a bug): the object is not estimated any more.
    Failed,
}

/// The trackers of several objects, in a fixed order.
pub struct Objects {
    slots: Vec<Slot>,
    background: bool,
}

impl Objects {
    /// Tracks each of `trackers`; acquisitions go to the background when there are
    /// several (a single object has nothing to keep tracking meanwhile).
    pub fn new(trackers: Vec<StreamTracker>) -> Self {
        Self {
            background: trackers.len() > 1,
            slots: trackers.into_iter().map(|t| Slot::Here(Box::new(t))).collect(),
        }
    }

    /// Takes back the trackers whose acquisition has finished, then has every tracker
    /// that is here read the frame (but one that would acquire while another acquisition
    /// runs: it waits). Fails, for every object, when the frame is unusable.
    pub fn prepare(&mut self, frame: &SbsBytes) -> Result<(), FrameError> {
        self.reclaim();
        let mut busy = self.slots.iter().any(|s| matches!(s, Slot::Away(_)));
        for slot in &mut self.slots {
            let Slot::Here(tracker) = slot else { continue };
            if self.background && busy && tracker.will_acquire() {
                tracker.skip();
                continue;
            }
            tracker.prepare(frame)?;
            busy |= self.background && tracker.acquiring();
        }
        Ok(())
    }

    /// Takes back the trackers whose acquisition thread has finished.
    fn reclaim(&mut self) {
        for slot in &mut self.slots {
            if !matches!(slot, Slot::Away(handle) if handle.is_finished()) {
                continue;
            }
            if let Slot::Away(handle) = std::mem::replace(slot, Slot::Failed) {
                match handle.join() {
                    Ok(tracker) => *slot = Slot::Here(tracker),
                    Err(_) => tracing::error!("an acquisition thread panicked; its object is dropped"),
                }
            }
        }
    }

    /// Searches the prepared frame: each object's outcome, in order.
    pub fn step(&mut self) -> Vec<Outcome> {
        let background = self.background;
        self.slots
            .iter_mut()
            .map(|slot| match slot {
                Slot::Here(tracker) if background && tracker.acquiring() => {
                    let Slot::Here(mut tracker) = std::mem::replace(slot, Slot::Failed) else {
                        return Outcome::Acquiring;
                    };
                    let spawned = std::thread::Builder::new()
                        .name("photopose-acquire".into())
                        .spawn(move || {
                            tracker.step();
                            tracker
                        });
                    match spawned {
                        Ok(handle) => *slot = Slot::Away(handle),
                        Err(e) => tracing::error!("cannot start an acquisition thread: {e}"),
                    }
                    Outcome::Acquiring
                }
                Slot::Here(tracker) => tracker.step().map_or(Outcome::Acquiring, Outcome::Estimate),
                Slot::Away(_) | Slot::Failed => Outcome::Acquiring,
            })
            .collect()
    }
}
