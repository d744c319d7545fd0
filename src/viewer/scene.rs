//! The entities of a recording and how a pose is drawn on them: the hand frame is the
//! 3D root (`world`, mm), the left camera hangs in it at `[hand_eye]` with its image
//! (`world/camera/image`), and each pose is the card as a box of its L × B, its outline
//! on the image, its trajectory and its figures over time.

use nalgebra::{Isometry3, Quaternion, UnitQuaternion};
use rerun::{Boxes3D, Color, EncodedImage, LineStrips2D, LineStrips3D, Pinhole, RecordingStream, Scalars, Transform3D};

use crate::camera::Intrinsics;
use crate::transport::messages::PoseMsg;
use crate::viewer::outline::card_outline;

/// The left camera in the hand frame.
pub const CAMERA: &str = "world/camera";
/// The left image and its pinhole.
pub const IMAGE: &str = "world/camera/image";
/// The frame-id time line: poses, truth and images of one frame line up on it.
pub const FRAME_TIMELINE: &str = "frame";
/// CLOCK_MONOTONIC of the frame's capture (the same clock in every process).
pub const CAPTURE_TIMELINE: &str = "capture_time";
/// How far in front of the camera its image is drawn in 3D, mm.
const IMAGE_PLANE_MM: f32 = 100.0;
/// Thickness of the card's box along its normal, mm (it is flat).
const CARD_THICKNESS_MM: f32 = 1.0;

/// What is logged as `estimate` or `truth`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// The estimator's pose.
    Estimate,
    /// The truth of a synthetic or recorded frame.
    Truth,
}

impl Kind {
    /// `"estimate"` or `"truth"`: the last part of the entity paths.
    pub fn name(self) -> &'static str {
        match self {
            Kind::Estimate => "estimate",
            Kind::Truth => "truth",
        }
    }
}

/// Sets both time lines to frame `frame_id` captured at `capture_time_ns`.
pub fn set_frame_time(rec: &RecordingStream, frame_id: u64, capture_time_ns: u64) {
    rec.set_time_sequence(FRAME_TIMELINE, frame_id as i64);
    rec.set_time(CAPTURE_TIMELINE, std::time::Duration::from_nanos(capture_time_ns));
}

/// The hand-frame transform `iso` (mm) as a Rerun transform.
pub fn transform(iso: &Isometry3<f64>) -> Transform3D {
    let t = iso.translation.vector.map(|v| v as f32);
    let q = iso.rotation.coords.map(|v| v as f32);
    Transform3D::from_translation_rotation([t.x, t.y, t.z], rerun::Quaternion::from_xyzw([q.x, q.y, q.z, q.w]))
}

/// The camera (static): its pose in the hand frame and its pinhole, for images of
/// `size` pixels seen through `camera`.
pub fn log_camera(
    rec: &RecordingStream,
    left_from_hand: &Isometry3<f64>,
    camera: &Intrinsics,
    size: (u32, u32),
) -> rerun::RecordingStreamResult<()> {
    // The hand frame's axes as the camera's (x right, y down, z forward) when `[hand_eye]`
    // is the identity: the 3D view starts upright.
    rec.log_static("world", &rerun::ViewCoordinates::RDF())?;
    rec.log_static(CAMERA, &transform(&left_from_hand.inverse()))?;
    let pinhole =
        Pinhole::from_focal_length_and_resolution([camera.fx as f32, camera.fy as f32], [size.0 as f32, size.1 as f32])
            .with_principal_point([camera.cx as f32, camera.cy as f32])
            .with_image_plane_distance(IMAGE_PLANE_MM);
    rec.log_static(IMAGE, &pinhole)
}

/// `img` compressed as a JPEG of `quality` (1–100).
pub fn jpeg(img: &image::RgbImage, quality: u8) -> Result<EncodedImage, jpeg_encoder::EncodingError> {
    let mut bytes = Vec::new();
    let (w, h) = (
        img.width().min(u16::MAX.into()) as u16,
        img.height().min(u16::MAX.into()) as u16,
    );
    jpeg_encoder::Encoder::new(&mut bytes, quality).encode(img.as_raw(), w, h, jpeg_encoder::ColorType::Rgb)?;
    Ok(EncodedImage::from_file_contents(bytes).with_media_type(rerun::MediaType::JPEG))
}

/// `H_T_O` of a pose message.
pub fn hand_from_model(p: &PoseMsg) -> Isometry3<f64> {
    let [w, x, y, z] = p.orientation_wxyz;
    Isometry3::from_parts(
        p.position_mm.into(),
        UnitQuaternion::from_quaternion(Quaternion::new(w, x, y, z)),
    )
}

/// How a pose is drawn: its colour, the model's strip width and the camera.
pub struct Drawing<'a> {
    /// Outline, box and trajectory colour.
    pub colour: [u8; 3],
    /// Width of the outer strip, in units of the card's length L (0: no strip).
    pub strip_per_length: f64,
    /// `CL_T_H`.
    pub left_from_hand: &'a Isometry3<f64>,
    /// The logged image's camera (scaled to its size), once known.
    pub camera: Option<Intrinsics>,
}

/// Pose `p` as `kind` at the current time: the card in 3D and its outline on the image.
pub fn log_pose(rec: &RecordingStream, kind: Kind, p: &PoseMsg, draw: &Drawing) -> rerun::RecordingStreamResult<()> {
    let name = kind.name();
    let at = hand_from_model(p);
    let colour = Color::from_rgb(draw.colour[0], draw.colour[1], draw.colour[2]);
    let half = [
        p.size_mm[0] as f32 / 2.0,
        p.size_mm[1] as f32 / 2.0,
        CARD_THICKNESS_MM / 2.0,
    ];
    rec.log(format!("world/{name}"), &transform(&at))?;
    rec.log(
        format!("world/{name}"),
        &Boxes3D::from_half_sizes([half]).with_colors([colour]),
    )?;
    if let Some(camera) = &draw.camera {
        let strip = draw.strip_per_length * p.size_mm[0];
        let lines = card_outline(&at, p.size_mm, strip, draw.left_from_hand, camera);
        rec.log(
            format!("{IMAGE}/{name}"),
            &LineStrips2D::new(lines).with_colors([colour]),
        )?;
    }
    Ok(())
}

/// The trajectory so far as one line in 3D.
pub fn log_trajectory(
    rec: &RecordingStream,
    kind: Kind,
    points: &[[f32; 3]],
    colour: [u8; 3],
) -> rerun::RecordingStreamResult<()> {
    let colour = Color::from_rgb(colour[0], colour[1], colour[2]);
    rec.log(
        format!("world/trajectory/{}", kind.name()),
        &LineStrips3D::new([points.to_vec()]).with_colors([colour]),
    )
}

/// One value of a time series at the current time.
pub fn scalar(rec: &RecordingStream, path: &str, value: f64) -> rerun::RecordingStreamResult<()> {
    rec.log(path, &Scalars::single(value))
}

/// x, y and z of pose `p` as `series/x/KIND`, `series/y/KIND`, `series/z/KIND`.
pub fn log_position(rec: &RecordingStream, kind: Kind, p: &PoseMsg) -> rerun::RecordingStreamResult<()> {
    for (axis, v) in ["x", "y", "z"].iter().zip(p.position_mm) {
        scalar(rec, &format!("series/{axis}/{}", kind.name()), v)?;
    }
    Ok(())
}
