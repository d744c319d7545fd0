//! Real-time options of the estimator (`[realtime]`): pin its threads to cores, run them
//! under SCHED_FIFO, lock its memory. Each option the system refuses (no permission, a
//! core that does not exist) is reported once as a warning and the estimator runs on
//! without it: a robot cell's service must not die over a scheduling wish.

use std::io;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::OnceLock;

use serde::Deserialize;

/// Cores a CPU set can name (`CPU_SETSIZE`).
pub const MAX_CPUS: usize = 1024;

/// `[realtime]`: what the estimator asks of the scheduler.
#[derive(Debug, Clone, Default, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RealtimeSettings {
    /// Cores the estimator's threads run on (empty: wherever the kernel puts them). The
    /// main thread, which runs tracking frames, takes the first; fitness workers the
    /// following ones in turn.
    pub cpus: Vec<usize>,
    /// SCHED_FIFO priority (1–99) of the estimator's threads; 0 keeps normal scheduling.
    pub fifo_priority: u8,
    /// Lock all of the process's memory (`mlockall`) so that no page fault stalls a frame.
    pub lock_memory: bool,
}

impl RealtimeSettings {
    /// Checks values before anything is applied: the problem, or `None`.
    pub fn problem(&self) -> Option<(&'static str, String)> {
        if self.fifo_priority > 99 {
            return Some(("fifo_priority", format!("{} must lie in 0–99", self.fifo_priority)));
        }
        if let Some(cpu) = self.cpus.iter().find(|&&c| c >= MAX_CPUS) {
            return Some(("cpus", format!("CPU {cpu} is beyond the {MAX_CPUS} a CPU set can name")));
        }
        None
    }

    /// The core of thread `slot` (0: the main thread, 1…: fitness workers).
    fn cpu_of(&self, slot: usize) -> Option<usize> {
        (!self.cpus.is_empty()).then(|| self.cpus[slot % self.cpus.len()])
    }
}

/// What one thread got.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ThreadOutcome {
    /// The core the thread is pinned to.
    pub pinned: Option<usize>,
    /// The SCHED_FIFO priority it runs at.
    pub fifo_priority: Option<u8>,
}

/// The settings fitness workers started later apply to themselves.
static PROCESS: OnceLock<RealtimeSettings> = OnceLock::new();

/// Applies `settings` to the process (memory) and the calling thread (slot 0), and keeps
/// them for the fitness workers, which apply them as they start ([`worker_started`]).
/// Returns the calling thread's outcome and whether memory is locked.
pub fn apply_to_process(settings: &RealtimeSettings) -> (ThreadOutcome, bool) {
    let _ = PROCESS.set(settings.clone());
    let locked = settings.lock_memory && lock_memory();
    (apply_to_thread(settings, 0), locked)
}

/// Called by each fitness worker as it starts (its index in the pool).
pub fn worker_started(index: usize) {
    if let Some(settings) = PROCESS.get() {
        apply_to_thread(settings, index + 1);
    }
}

/// Applies the thread options of `settings` to the calling thread as thread `slot`.
pub fn apply_to_thread(settings: &RealtimeSettings, slot: usize) -> ThreadOutcome {
    static PIN_WARNED: AtomicBool = AtomicBool::new(false);
    static FIFO_WARNED: AtomicBool = AtomicBool::new(false);
    let pinned = settings.cpu_of(slot).filter(|&cpu| match pin(cpu) {
        Ok(()) => true,
        Err(e) => {
            warn_once(
                &PIN_WARNED,
                format!("cannot pin an estimator thread to CPU {cpu} ({e}); it runs unpinned"),
            );
            false
        }
    });
    let fifo_priority = Some(settings.fifo_priority)
        .filter(|&p| p > 0)
        .filter(|&p| match set_fifo(p) {
            Ok(()) => true,
            Err(e) => {
                warn_once(
                    &FIFO_WARNED,
                    format!(
                        "SCHED_FIFO priority {p} refused ({e}); normal scheduling instead \
                         (needs root, CAP_SYS_NICE or an rtprio limit)"
                    ),
                );
                false
            }
        });
    ThreadOutcome { pinned, fifo_priority }
}

fn warn_once(flag: &AtomicBool, message: String) {
    if !flag.swap(true, Ordering::Relaxed) {
        tracing::warn!("realtime: {message}");
    }
}

/// Pins the calling thread to `cpu`.
fn pin(cpu: usize) -> io::Result<()> {
    if cpu >= MAX_CPUS {
        return Err(io::Error::from(io::ErrorKind::InvalidInput));
    }
    // SAFETY: the set is a plain bit array owned here; pid 0 is the calling thread.
    unsafe {
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        libc::CPU_SET(cpu, &mut set);
        if libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &set) != 0 {
            return Err(io::Error::last_os_error());
        }
    }
    Ok(())
}

/// Runs the calling thread under SCHED_FIFO at `priority`.
fn set_fifo(priority: u8) -> io::Result<()> {
    let param = libc::sched_param {
        sched_priority: i32::from(priority),
    };
    // SAFETY: pthread_self is the calling thread; param lives across the call.
    match unsafe { libc::pthread_setschedparam(libc::pthread_self(), libc::SCHED_FIFO, &param) } {
        0 => Ok(()),
        code => Err(io::Error::from_raw_os_error(code)),
    }
}

/// Locks current and future memory; false (with a warning) when refused.
fn lock_memory() -> bool {
    // SAFETY: mlockall takes flags only.
    if unsafe { libc::mlockall(libc::MCL_CURRENT | libc::MCL_FUTURE) } == 0 {
        return true;
    }
    tracing::warn!(
        "realtime: mlockall refused ({}); memory stays pageable (raise `ulimit -l` or grant CAP_IPC_LOCK)",
        io::Error::last_os_error()
    );
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The calling thread's cores and scheduling policy and priority, as the kernel sees them.
    fn current_thread() -> io::Result<(Vec<usize>, i32, i32)> {
        // SAFETY: out-parameters owned here; pid 0 and pthread_self are the calling thread.
        unsafe {
            let mut set: libc::cpu_set_t = std::mem::zeroed();
            if libc::sched_getaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &mut set) != 0 {
                return Err(io::Error::last_os_error());
            }
            let cpus = (0..MAX_CPUS).filter(|&c| libc::CPU_ISSET(c, &set)).collect();
            let (mut policy, mut param) = (0, std::mem::zeroed::<libc::sched_param>());
            match libc::pthread_getschedparam(libc::pthread_self(), &mut policy, &mut param) {
                0 => Ok((cpus, policy, param.sched_priority)),
                code => Err(io::Error::from_raw_os_error(code)),
            }
        }
    }

    /// Runs `f` on a fresh thread, so the test runner's threads keep their settings.
    fn on_thread<T: Send + 'static>(f: impl FnOnce() -> T + Send + 'static) -> T {
        std::thread::spawn(f).join().expect("test thread")
    }

    #[test]
    fn pinning_moves_the_thread_and_cycles_through_the_list() {
        let settings = RealtimeSettings {
            cpus: vec![0],
            ..Default::default()
        };
        let (outcome, now) = on_thread(move || (apply_to_thread(&settings, 3), current_thread().unwrap()));
        assert_eq!(outcome.pinned, Some(0));
        assert_eq!(now.0, vec![0]);
        let two = RealtimeSettings {
            cpus: vec![4, 7],
            ..Default::default()
        };
        assert_eq!([0, 1, 2].map(|s| two.cpu_of(s)), [Some(4), Some(7), Some(4)]);
        assert_eq!(RealtimeSettings::default().cpu_of(0), None);
    }

    #[test]
    fn a_missing_core_is_refused_and_the_thread_runs_on() {
        let settings = RealtimeSettings {
            cpus: vec![MAX_CPUS - 1],
            ..Default::default()
        };
        let (outcome, before, after) = on_thread(move || {
            let before = current_thread().unwrap();
            (apply_to_thread(&settings, 0), before, current_thread().unwrap())
        });
        assert_eq!(outcome.pinned, None);
        assert_eq!(before, after);
        assert_eq!(pin(MAX_CPUS).unwrap_err().kind(), io::ErrorKind::InvalidInput);
    }

    #[test]
    fn fifo_priority_is_applied_or_refused_as_reported() {
        let settings = RealtimeSettings {
            fifo_priority: 1,
            ..Default::default()
        };
        let (outcome, (_, policy, priority)) =
            on_thread(move || (apply_to_thread(&settings, 0), current_thread().unwrap()));
        match outcome.fifo_priority {
            Some(p) => assert_eq!((policy, priority), (libc::SCHED_FIFO, i32::from(p))),
            None => assert_eq!(policy, libc::SCHED_OTHER, "refused yet changed"),
        }
        let normal = on_thread(|| apply_to_thread(&RealtimeSettings::default(), 0));
        assert_eq!(normal, ThreadOutcome::default());
    }

    #[test]
    fn settings_out_of_range_are_named() {
        let bad = RealtimeSettings {
            fifo_priority: 120,
            ..Default::default()
        };
        assert_eq!(bad.problem(), Some(("fifo_priority", "120 must lie in 0–99".into())));
        let far = RealtimeSettings {
            cpus: vec![0, 4096],
            ..Default::default()
        };
        assert_eq!(far.problem().map(|p| p.0), Some("cpus"));
        assert_eq!(RealtimeSettings::default().problem(), None);
    }
}
