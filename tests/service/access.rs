//! Who may read the shared memory: photopose's iceoryx2 files belong to its user alone.

use std::time::Duration;

use crate::process::{estimator, ipc_entries, serial, spawn, Watcher};

/// Every file iceoryx2 makes for photopose (shared memory, records, sockets) is readable
/// and writable by its user only.
#[test]
fn shared_memory_is_private_to_the_user() {
    let _serial = serial();
    let mut w = Watcher::new("photopose-test-access");
    let _capture = spawn(&["capture"]);
    let _estimator = estimator();
    assert!(w.until_pose(Duration::from_secs(10)), "no pose");
    let entries = ipc_entries();
    let shm = entries.iter().filter(|(p, _)| p.starts_with("/dev/shm")).count();
    println!("{} entries ({shm} in /dev/shm)", entries.len());
    assert!(shm >= 6, "frames, poses, truth and their events: {entries:?}");
    let open: Vec<_> = entries.iter().filter(|(_, mode)| mode & 0o077 != 0).collect();
    assert!(open.is_empty(), "accessible to group or others: {open:?}");
}
