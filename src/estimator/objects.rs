//! Objects on one frame stream, each with a [`StreamTracker`] (a population) of its own.
//! Tracking frames run on the caller's thread, one object after the other. An object
//! that must be searched on a whole frame (acquired, or recovered once lost) is searched
//! on a thread of its own, so that every frame still gets an answer (`searching` for that
//! object, while the others go on being tracked). The frames that arrive meanwhile are
//! kept for it ([`Backlog`]); once its search is done the thread tracks it through them
//! (a few milliseconds each), and the object rejoins at the newest frame with the motion
//! followed, instead of relocating a pose a second old. One search runs at a time, with
//! all fitness workers: two at once would each take twice as long. The thread reads its
//! frame from a copy (the camera's sample is released at once).

use std::collections::VecDeque;
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

use crate::estimator::tracking::{Estimate, FrameError, StreamTracker};
use crate::vision::lookup::SbsBytes;
use crate::vision::PixelFormat;

/// What one object gave on a frame.
#[derive(Debug, Clone, Copy)]
pub enum Outcome {
    /// Its estimate on this frame.
    Estimate(Estimate),
    /// It is being searched in the background: no estimate on this frame.
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

/// Bytes of frames a backlog holds at most: 256 MiB, about 1.5 s of HD RGB8 at 30 fps
/// (46 frames), 0.8 s at 60 fps, and longer for YUYV. An acquisition takes 0.3–0.8 s.
pub const BACKLOG_BYTES: usize = 256 << 20;

/// The frames that arrived while an object was searched on a whole frame, oldest first,
/// within `budget` bytes: when a frame would exceed it, every second frame is dropped
/// (the newest kept), so the backlog still spans the whole search at a lower rate.
pub struct Backlog<T> {
    frames: VecDeque<(T, usize)>,
    bytes: usize,
    budget: usize,
}

impl<T> Backlog<T> {
    /// An empty backlog of at most `budget` bytes.
    pub fn new(budget: usize) -> Self {
        Self {
            frames: VecDeque::new(),
            bytes: 0,
            budget,
        }
    }

    /// Adds the newest frame, of `bytes` bytes, thinning the older ones if need be.
    pub fn push(&mut self, frame: T, bytes: usize) {
        while self.bytes + bytes > self.budget && !self.frames.is_empty() {
            self.thin();
        }
        self.bytes += bytes;
        self.frames.push_back((frame, bytes));
    }

    /// Drops every second frame, counting back from the newest (which stays).
    fn thin(&mut self) {
        let n = self.frames.len();
        let mut k = 0;
        self.frames.retain(|_| {
            k += 1;
            (n - k).is_multiple_of(2)
        });
        if self.frames.len() == n {
            self.frames.clear();
        }
        self.bytes = self.frames.iter().map(|f| f.1).sum();
    }

    /// Takes the oldest frame.
    pub fn pop(&mut self) -> Option<T> {
        let (frame, bytes) = self.frames.pop_front()?;
        self.bytes -= bytes;
        Some(frame)
    }

    /// Frames held.
    pub fn len(&self) -> usize {
        self.frames.len()
    }

    /// Whether no frame is held.
    pub fn is_empty(&self) -> bool {
        self.frames.is_empty()
    }
}

/// A backlog shared by the caller, who adds frames, and the search's thread.
type SharedBacklog = Arc<Mutex<Backlog<OwnedFrame>>>;

/// Where an object's tracker is.
enum Slot {
    /// Ready for the next frame.
    Here(Box<StreamTracker>),
    /// To be searched on this copy of the frame, in the background.
    Due(Box<StreamTracker>, OwnedFrame),
    /// Searched on its own thread, which then tracks it through the backlog and hands
    /// the tracker back.
    Away(JoinHandle<Box<StreamTracker>>, SharedBacklog),
    /// Its search thread died (a bug): the object is not estimated any more.
    Failed,
}

/// The trackers of the objects, in a fixed order.
pub struct Objects {
    slots: Vec<Slot>,
}

impl Objects {
    /// Tracks each of `trackers`.
    pub fn new(trackers: Vec<StreamTracker>) -> Self {
        Self {
            slots: trackers.into_iter().map(|t| Slot::Here(Box::new(t))).collect(),
        }
    }

    /// Takes back the trackers whose search has finished, then has every tracker that is
    /// here read the frame. One that must search the whole frame keeps a copy of it
    /// instead, or waits while another search runs; one away gets a copy in its backlog.
    /// Fails, for every object, when the frame is unusable.
    pub fn prepare(&mut self, frame: &SbsBytes) -> Result<(), FrameError> {
        self.reclaim();
        let mut busy = self.slots.iter().any(|s| matches!(s, Slot::Away(..)));
        for slot in &mut self.slots {
            match slot {
                Slot::Here(tracker) if !tracker.will_acquire() => tracker.prepare(frame)?,
                Slot::Here(tracker) => {
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
                Slot::Away(_, backlog) => {
                    let copy = OwnedFrame::copy(frame);
                    let bytes = copy.bytes.len();
                    backlog.lock().unwrap_or_else(|e| e.into_inner()).push(copy, bytes);
                }
                Slot::Due(..) | Slot::Failed => {}
            }
        }
        Ok(())
    }

    /// Takes back the trackers whose search thread has finished.
    fn reclaim(&mut self) {
        for slot in &mut self.slots {
            if !matches!(slot, Slot::Away(handle, _) if handle.is_finished()) {
                continue;
            }
            if let Slot::Away(handle, _) = std::mem::replace(slot, Slot::Failed) {
                match handle.join() {
                    Ok(tracker) => *slot = Slot::Here(tracker),
                    Err(_) => tracing::error!("a search thread panicked; its object is dropped"),
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
                Slot::Away(..) | Slot::Failed => Outcome::Acquiring,
            })
            .collect()
    }

    /// `tracker` reading `frame` and searching it on a thread of its own, then tracking
    /// through the backlog.
    fn away(mut tracker: Box<StreamTracker>, frame: OwnedFrame) -> Slot {
        let backlog: SharedBacklog = Arc::new(Mutex::new(Backlog::new(BACKLOG_BYTES)));
        let kept = backlog.clone();
        let spawned = std::thread::Builder::new()
            .name("photopose-acquire".into())
            .spawn(move || {
                match tracker.prepare(&frame.view()) {
                    Ok(()) => _ = tracker.step(),
                    Err(e) => tracing::warn!("acquisition frame: {e}"),
                }
                drop(frame);
                catch_up(&mut tracker, &kept);
                tracker
            });
        match spawned {
            Ok(handle) => Slot::Away(handle, backlog),
            Err(e) => {
                tracing::error!("cannot start an acquisition thread: {e}");
                Slot::Failed
            }
        }
    }
}

/// Tracks `tracker` through the frames of `backlog` until it is empty, or until the
/// tracker needs another whole-frame search (which the newest frame will get).
fn catch_up(tracker: &mut StreamTracker, backlog: &Mutex<Backlog<OwnedFrame>>) {
    tracker.follow_on();
    let (start, mut frames) = (std::time::Instant::now(), 0);
    while !tracker.will_acquire() {
        let Some(frame) = backlog.lock().unwrap_or_else(|e| e.into_inner()).pop() else {
            break;
        };
        match tracker.prepare(&frame.view()) {
            Ok(()) => _ = tracker.step(),
            Err(e) => tracing::warn!("backlog frame: {e}"),
        }
        frames += 1;
    }
    tracing::debug!(
        "caught up on {frames} frames in {:.0} ms",
        start.elapsed().as_secs_f64() * 1e3
    );
}

#[cfg(test)]
mod tests {
    use super::Backlog;

    fn held(b: &mut Backlog<u32>) -> Vec<u32> {
        std::iter::from_fn(|| b.pop()).collect()
    }

    #[test]
    fn a_backlog_gives_its_frames_oldest_first() {
        let mut b = Backlog::new(100);
        for i in 0..5 {
            b.push(i, 10);
        }
        assert_eq!(b.len(), 5);
        assert_eq!(held(&mut b), [0, 1, 2, 3, 4]);
        assert!(b.is_empty());
    }

    #[test]
    fn a_full_backlog_keeps_every_second_frame_and_the_newest() {
        let mut b = Backlog::new(40);
        for i in 0..5 {
            b.push(i, 10);
        }
        // 0–3 filled it; 4 thinned it to 1 and 3.
        assert_eq!(held(&mut b), [1, 3, 4]);
        let mut b = Backlog::new(35);
        for i in 0..9 {
            b.push(i, 10);
        }
        assert!(b.bytes <= 35, "{} bytes", b.bytes);
        assert_eq!(held(&mut b).last(), Some(&8));
    }

    #[test]
    fn a_frame_larger_than_the_budget_replaces_the_backlog() {
        let mut b = Backlog::new(20);
        b.push(1, 10);
        b.push(2, 50);
        assert_eq!(held(&mut b), [2]);
    }
}
