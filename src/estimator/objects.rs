//! Several objects on one frame stream, each with a [`StreamTracker`] (a population) of
//! its own. Tracking frames run on the caller's thread, one object after the other. With
//! more than one object, an object that must be (re)acquired is searched on a thread of
//! its own, so the others go on being tracked on every frame meanwhile; it rejoins
//! when its search is done. One acquisition runs at a time, with all fitness workers:
//! two at once would each take twice as long, and an acquisition's answer is only as
//! good as it is fresh. The thread also reads the frame (a copy: the camera's sample is
//! released at once), which takes 50–100 ms at HD; the relocation after an acquisition
//! runs the same way.

use std::thread::JoinHandle;

use crate::estimator::tracking::{Estimate, FrameError, StreamTracker};
use crate::vision::lookup::SbsBytes;
use crate::vision::PixelFormat;

/// What one object gave on a frame.
#[derive(Debug, Clone, Copy)]
pub enum Outcome {
    /// Its estimate on this frame.
    Estimate(Estimate),
    /// It is being acquired in the background: no estimate on this frame.
    Acquiring,
}

/// A copy of a frame for a search on another thread.
struct OwnedFrame {
    bytes: Vec<u8>,
    width: usize,
    height: usize,
    row_stride: usize,
    format: PixelFormat,
}

impl OwnedFrame {
    fn copy(frame: &SbsBytes) -> Self {
        Self {
            bytes: frame.bytes.to_vec(),
            width: frame.width,
            height: frame.height,
            row_stride: frame.row_stride,
            format: frame.format,
        }
    }

    fn view(&self) -> SbsBytes<'_> {
        SbsBytes {
            bytes: &self.bytes,
            width: self.width,
            height: self.height,
            row_stride: self.row_stride,
            format: self.format,
        }
    }
}

/// Where an object's tracker is.
enum Slot {
    /// Ready for the next frame.
    Here(Box<StreamTracker>),
    /// To be (re)acquired or relocated on this copy of the frame, in the background.
    Due(Box<StreamTracker>, OwnedFrame),
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
    /// that is here read the frame. In the background, one that must acquire keeps a copy
    /// of the frame instead, or waits while another acquisition runs. Fails, for every
    /// object, when the frame is unusable.
    pub fn prepare(&mut self, frame: &SbsBytes) -> Result<(), FrameError> {
        self.reclaim();
        let mut busy = self.slots.iter().any(|s| matches!(s, Slot::Away(_)));
        for slot in &mut self.slots {
            let Slot::Here(tracker) = slot else { continue };
            if !(self.background && tracker.will_acquire()) {
                tracker.prepare(frame)?;
                continue;
            }
            tracker.skip();
            tracker.check(frame)?;
            if !busy {
                let Slot::Here(tracker) = std::mem::replace(slot, Slot::Failed) else {
                    continue;
                };
                *slot = Slot::Due(tracker, OwnedFrame::copy(frame));
                busy = true;
            }
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
        self.slots
            .iter_mut()
            .map(|slot| match slot {
                Slot::Due(..) => {
                    if let Slot::Due(tracker, frame) = std::mem::replace(slot, Slot::Failed) {
                        *slot = Self::away(tracker, frame);
                    }
                    Outcome::Acquiring
                }
                Slot::Here(tracker) => tracker.step().map_or(Outcome::Acquiring, Outcome::Estimate),
                Slot::Away(_) | Slot::Failed => Outcome::Acquiring,
            })
            .collect()
    }

    /// `tracker` reading `frame` and searching it on a thread of its own.
    fn away(mut tracker: Box<StreamTracker>, frame: OwnedFrame) -> Slot {
        let spawned = std::thread::Builder::new()
            .name("photopose-acquire".into())
            .spawn(move || {
                match tracker.prepare(&frame.view()) {
                    Ok(()) => _ = tracker.step(),
                    Err(e) => tracing::warn!("acquisition frame: {e}"),
                }
                tracker
            });
        match spawned {
            Ok(handle) => Slot::Away(handle),
            Err(e) => {
                tracing::error!("cannot start an acquisition thread: {e}");
                Slot::Failed
            }
        }
    }
}
