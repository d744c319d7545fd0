//! Frames that lie about themselves: the estimator process skips them, counts them and
//! keeps tracking.

use std::io::Read;
use std::process::Stdio;
use std::time::Duration;

use photopose::transport::ipc::Ipc;
use photopose::transport::messages::monotonic_ns;

use crate::common::data;
use crate::process::{model, photopose, serial, Running, Watcher};

/// Frames whose header disagrees with the payload reach the estimator over shared
/// memory: it skips and counts each, keeps running, and tracks the next good frame.
#[test]
fn the_estimator_skips_frames_whose_header_disagrees_with_the_payload() {
    use photopose::transport::ipc::wake_up;
    use photopose::transport::messages::{pixel_format, FrameHeader, FRAMES_SERVICE};
    let _serial = serial();
    let frame = image::open(data("examples/rocket-frame.jpg"))
        .expect("example frame")
        .to_rgb8();
    let (w, h) = (frame.width() / 2, frame.height());
    let stride = 2 * w * 3;
    let good = FrameHeader {
        width: w,
        height: h,
        pixel_format: pixel_format::RGB8,
        row_stride: stride,
        ..Default::default()
    };
    let len = (stride * h) as usize;
    let bad = [
        (
            FrameHeader {
                pixel_format: 7,
                ..good
            },
            len,
        ),
        (FrameHeader { width: 0, ..good }, len),
        (
            FrameHeader {
                row_stride: stride - 3,
                ..good
            },
            len,
        ),
        (good, len - 1),
        (FrameHeader { height: h + 1, ..good }, len),
    ];
    let ipc = Ipc::new("photopose-test-bad-frames").expect("node");
    let publisher = ipc.frame_publisher(len).expect("frame publisher");
    let waker = ipc.waker(FRAMES_SERVICE).expect("waker");
    let mut w = Watcher::new("photopose-test-bad-frames-poses");
    let process = photopose()
        .args(["estimator", "--model", &model(), "--seconds", "8"])
        .env("RUST_LOG", "photopose=info")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("estimator");
    let mut process = Running(process);
    std::thread::sleep(Duration::from_millis(800));
    let send = |id: u64, header: FrameHeader, len: usize| {
        let mut sample = publisher.loan_slice(len).expect("loan");
        let n = len.min(frame.as_raw().len());
        sample.payload_mut()[..n].copy_from_slice(&frame.as_raw()[..n]);
        *sample.user_header_mut() = FrameHeader {
            frame_id: id,
            capture_time_ns: monotonic_ns(),
            publish_time_ns: monotonic_ns(),
            ..header
        };
        sample.send().expect("send");
        wake_up(&waker);
        // One at a time: the estimator always takes the newest frame.
        std::thread::sleep(Duration::from_millis(200));
    };
    for (i, (header, len)) in bad.into_iter().enumerate() {
        send(i as u64, header, len);
    }
    assert!(
        w.got.is_empty() && !w.until_pose(Duration::from_millis(100)),
        "a pose for a bad frame"
    );
    send(10, good, len);
    assert!(
        w.until_pose(Duration::from_secs(5)),
        "no pose for the good frame after the bad ones"
    );
    assert_eq!(w.got[0].0.frame_id, 10);
    let mut err = String::new();
    process.0.wait().expect("estimator exits after --seconds");
    process
        .0
        .stderr
        .take()
        .expect("stderr")
        .read_to_string(&mut err)
        .unwrap();
    assert!(
        err.contains("estimator: 1 frames processed, 0 dropped, skipped: 1 unknown pixel format, 1 empty image, 1 short stride, 2 wrong length"),
        "{err}"
    );
    for reason in [
        "unknown pixel format code 7",
        "empty image (0x720 per eye)",
        "row stride 7677 is shorter",
    ] {
        assert!(err.contains(reason), "{reason:?} not logged: {err}");
    }
}
