//! Lookup images against the per-pixel reference: texel packing, RGB8 and YUYV rows,
//! refilled regions and the padded ring.

use super::*;
use crate::vision::color::rgb_to_hsv;

fn rule(second: SecondByte) -> TexelRule {
    TexelRule {
        classes: ColorClasses::default(),
        second,
        gains: [1.0; 3],
    }
}

#[test]
fn image_is_framed_by_outside_texels() {
    let plane = ColorPlane {
        width: 3,
        height: 2,
        px: (0..6)
            .map(|i| PixelColor {
                code: i as u8,
                sat: 10 * i as u8 + 120,
                hue: 7,
            })
            .collect(),
    };
    let img = LookupImage::new(&plane, &rule(SecondByte::Saturation));
    assert_eq!((img.width, img.height, img.origin), (5, 4, (0, 0)));
    assert!(img.px[..5].iter().all(|&t| t == OUTSIDE_TEXEL));
    assert!(img.px[15..].iter().all(|&t| t == OUTSIDE_TEXEL));
    assert_eq!([img.px[5], img.px[9]], [OUTSIDE_TEXEL; 2]);
    // Pixel (2, 1) is texel (3, 2): code 5, saturation 170.
    assert_eq!(img.px[2 * 5 + 3], 5 | 170 << 8);
    assert_eq!(img.px[5 + 1], 120 << 8);
    // The paper's outer test reads the raw hue instead.
    let raw = LookupImage::new(&plane, &rule(SecondByte::RawHue));
    assert_eq!(raw.px[2 * 5 + 3], 5 | 7 << 8);
}

/// Every RGB colour: the row conversion equals the scalar HSV, classes and rule.
#[test]
fn row_conversion_equals_the_scalar_path_on_every_colour() {
    for second in [SecondByte::Saturation, SecondByte::RawHue] {
        let rule = rule(second);
        let mut rgb = vec![0u8; 3 * 256];
        let mut out = vec![0; 256];
        for r in 0..=255u8 {
            for g in 0..=255u8 {
                for (b, p) in rgb.chunks_exact_mut(3).enumerate() {
                    p.copy_from_slice(&[r, g, b as u8]);
                }
                rule.rgb_row(&rgb, &mut out);
                for (b, &t) in out.iter().enumerate() {
                    let (h, s, v) = rgb_to_hsv(r, g, b as u8);
                    let want = rule.texel(rule.classes.code(h, s, v), s, h);
                    assert_eq!(t, want, "rgb {r} {g} {b} ({second:?})");
                }
            }
        }
    }
}

/// Gains scale a pixel before it is classed, so a dimmed pixel gets its class back; a
/// clipped pixel keeps its own (white stays white).
#[test]
fn gains_restore_the_class_of_a_dimmed_pixel_and_keep_clipped_ones() {
    let rule = rule(SecondByte::Saturation);
    let classed = |rule: &TexelRule, px: [u8; 3]| {
        let mut out = [0; 1];
        rule.rgb_row(&px, &mut out);
        (out[0] & 0xff) as u8
    };
    // A light grey at half exposure reads black; doubled it is grey again.
    assert_eq!(classed(&rule, [120, 120, 120]), GRAY);
    assert_eq!(classed(&rule, [40, 40, 40]), BLACK);
    assert_eq!(classed(&rule.with_gains([3.0; 3]), [40, 40, 40]), GRAY);
    // A white balance shifted toward red: the gains bring the hue back.
    let (hue, _, _) = rgb_to_hsv(60, 120, 200);
    assert_eq!(classed(&rule.with_gains([0.5, 1.0, 1.25]), [120, 120, 160]), hue);
    // Over-exposed: kept as it is, not darkened to grey.
    assert_eq!(classed(&rule.with_gains([0.7; 3]), [255, 255, 255]), WHITE);
    // Unit gains change nothing (the other tests check every colour with them).
    assert_eq!(rule.with_gains([1.0; 3]), rule);
}

/// Every YUV triple: the YUYV row path equals BT.601 to RGB, then the RGB reference.
#[test]
fn yuyv_rows_equal_the_reference_conversion_on_every_colour() {
    for second in [SecondByte::Saturation, SecondByte::RawHue] {
        let rule = rule(second);
        let mut yuyv = vec![0u8; 2 * 256];
        let mut out = vec![0; 256];
        for u in 0..=255u8 {
            for v in 0..=255u8 {
                for (k, q) in yuyv.chunks_exact_mut(4).enumerate() {
                    q.copy_from_slice(&[2 * k as u8, u, 2 * k as u8 + 1, v]);
                }
                rule.yuyv_row(&yuyv, &mut out);
                for (y, &t) in out.iter().enumerate() {
                    let (r, g, b) = yuv_to_rgb(y as u8, u, v);
                    let (h, s, val) = rgb_to_hsv(r, g, b);
                    let want = rule.texel(rule.classes.code(h, s, val), s, h);
                    assert_eq!(t, want, "yuv {y} {u} {v} ({second:?})");
                }
            }
        }
    }
}

/// YUYV regions (odd and even edges, both eyes) read as their RGB conversion does.
#[test]
fn raw_side_by_side_buffers_split_into_eyes() {
    let mut sbs = RgbImage::from_pixel(6, 2, image::Rgb([1, 2, 3]));
    sbs.put_pixel(3, 1, image::Rgb([200, 100, 50]));
    // Rows padded to 20 bytes.
    let mut bytes = vec![0u8; 20 * 2];
    for y in 0..2 {
        bytes[y * 20..y * 20 + 18].copy_from_slice(&sbs.as_raw()[y * 18..y * 18 + 18]);
    }
    let frame = |bytes, row_stride| SbsBytes {
        bytes,
        width: 3,
        height: 2,
        row_stride,
        format: PixelFormat::Rgb8,
    };
    let st = frame(&bytes, 20).to_images().unwrap();
    assert_eq!(st.to_sbs(), sbs);
    assert_eq!(frame(&bytes, 20).rgb_at(1, 0, 1), Some([200, 100, 50]));
    assert_eq!(frame(&bytes, 20).rgb_at(0, 3, 0), None, "past the eye's width");
    assert!(frame(&bytes[..37], 20).to_images().is_none());
    assert!(frame(&bytes, 17).to_images().is_none());
}

#[test]
fn yuyv_refill_equals_the_refill_of_its_rgb_conversion() {
    use rand::{Rng, SeedableRng};
    let (w, h) = (10, 3);
    let mut rng = rand::rngs::StdRng::seed_from_u64(3);
    let stride = 2 * w * 2 + 4;
    let yuyv: Vec<u8> = (0..stride * h).map(|_| rng.random()).collect();
    let frame = SbsBytes {
        bytes: &yuyv,
        width: w,
        height: h,
        row_stride: stride,
        format: PixelFormat::Yuyv,
    };
    assert!(frame.is_complete());
    let rgb = frame.to_images().unwrap().to_sbs();
    // Single pixels read as the whole conversion (even and odd, both eyes).
    for (eye, u, v) in [(0, 4, 1), (0, 7, 2), (1, 0, 0), (1, 9, 2)] {
        let want = rgb.get_pixel((eye * w + u) as u32, v as u32).0;
        assert_eq!(frame.rgb_at(eye, u, v), Some(want), "eye {eye} ({u}, {v})");
    }
    assert_eq!(frame.rgb_at(0, 0, h), None, "below the image");
    let rgb_frame = SbsBytes {
        bytes: rgb.as_raw(),
        width: w,
        height: h,
        row_stride: 2 * w * 3,
        format: PixelFormat::Rgb8,
    };
    let rule = rule(SecondByte::Saturation);
    let (mut a, mut b) = (LookupImage::with_capacity(w, h), LookupImage::with_capacity(w, h));
    let capacity = a.px.capacity();
    for eye in 0..2 {
        for cols in [0..10, 1..10, 1..9, 2..7, 3..4, 4..5, 9..12, 5..5] {
            let roi = Region { cols, rows: 1..3 };
            a.refill(&frame, eye, &roi, &rule);
            b.refill(&rgb_frame, eye, &roi, &rule);
            assert_eq!((a.width, a.height, a.origin), (b.width, b.height, b.origin), "{roi:?}");
            assert_eq!(a.px, b.px, "eye {eye} {roi:?}");
        }
    }
    assert_eq!(a.px.capacity(), capacity, "no reallocation");
    // An odd eye width cannot be YUYV; a short payload is incomplete.
    assert!(!SbsBytes { width: 5, ..frame }.is_complete());
    assert!(!SbsBytes {
        bytes: &yuyv[..stride * 2],
        ..frame
    }
    .is_complete());
}

#[test]
fn whole_images_convert_like_the_scalar_colour_plane() {
    let img = RgbImage::from_fn(37, 5, |x, y| image::Rgb([(x * 7) as u8, (y * 50) as u8, (x * y) as u8]));
    let rule = rule(SecondByte::Saturation);
    let fast = LookupImage::from_rgb(&img, &rule);
    let scalar = LookupImage::new(&ColorPlane::from_rgb(&img, &rule.classes), &rule);
    assert_eq!(
        (fast.width, fast.height, &fast.px),
        (scalar.width, scalar.height, &scalar.px)
    );
}

#[test]
fn refill_covers_the_region_only() {
    // A 6×2 side-by-side frame (eyes 3×2), rows padded to 20 bytes; left eye red,
    // right eye blue.
    let mut bytes = vec![0u8; 40];
    for y in 0..2 {
        for x in 0..6 {
            let c = if x < 3 { [255, 0, 0] } else { [0, 0, 255] };
            bytes[y * 20 + 3 * x..][..3].copy_from_slice(&c);
        }
    }
    let frame = SbsBytes {
        bytes: &bytes,
        width: 3,
        height: 2,
        row_stride: 20,
        format: PixelFormat::Rgb8,
    };
    assert!(frame.is_complete());
    let rule = rule(SecondByte::Saturation);
    let mut img = LookupImage::with_capacity(3, 2);
    let capacity = img.px.capacity();
    let roi = Region { cols: 1..9, rows: 1..2 };
    img.refill(&frame, 1, &roi, &rule);
    assert_eq!((img.width, img.height, img.origin), (4, 3, (1, 1)));
    assert_eq!(img.px[4 + 1], texel(120, 255));
    assert_eq!(img.px[4 + 2], texel(120, 255));
    assert_eq!(img.px.iter().filter(|&&t| t == OUTSIDE_TEXEL).count(), 10);
    img.refill(&frame, 0, &Region { cols: 0..3, rows: 0..2 }, &rule);
    assert_eq!(img.px[5 + 1], texel(0, 255));
    assert_eq!(img.px.capacity(), capacity, "no reallocation");
}
