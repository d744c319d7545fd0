//! The suite's scenes, one line each: resolution, card photo and wall, the card's
//! position (mm) and rotation (x, y, z degrees) in the left-camera frame and its length
//! (mm, breadth by the photo box's aspect unless stretched), then what makes it special.

use super::{scene, Blur, Card, Case, Patch, Texture};

/// The card photos and their boxes `[x, y, w, h]`, as given to `photopose model --box`.
pub const CUP: Card = Card::new("coffee.jpg", [149, 22, 279, 289]);
pub const CAT: Card = Card::new("chelsea.jpg", [70, 20, 280, 270]);
pub const ASTRO: Card = Card::new("astronaut.jpg", [120, 20, 270, 330]);
pub const ROCKET: Card = Card::new("rocket.jpg", [150, 60, 340, 300]);
pub const BOWL: Card = Card::new("bowl.jpg", [230, 110, 520, 380]);
pub const HOPPER: Card = Card::new("hopper.jpg", [100, 20, 340, 480]);

/// The walls (`tests/data/backgrounds/`).
const ROOM: &str = "room.jpg";
const DOGS: &str = "dogs.jpg";
const BRUSHES: &str = "brushes.jpg";
const CUPS: &str = "cups.jpg";
const BOATS: &str = "boats.jpg";
const CREEK: &str = "creek.jpg";
const MARIGOLD: &str = "marigold.jpg";

/// White balance of a camera set for daylight under warm light, and the reverse.
const WARM: [f64; 3] = [1.15, 1.0, 0.85];
const COOL: [f64; 3] = [0.87, 1.0, 1.13];
/// Occluder colours: grey cardboard and coloured bars.
const GREY: [u8; 3] = [128, 128, 128];
const GREEN: [u8; 3] = [90, 110, 60];
const RED: [u8; 3] = [200, 40, 30];
const BLUE: [u8; 3] = [40, 80, 200];
const ORANGE: [u8; 3] = [230, 130, 30];

/// A same-hue patch beside the card, at `at` card extents from its centre, `scale`
/// times its size.
const fn patch(at: [f64; 2], scale: f64) -> Patch {
    Patch { at, scale }
}

/// Every scene, clean ones first.
pub fn all() -> Vec<Case> {
    let mut all = clean();
    all.extend(hard());
    all
}

/// Scenes with the card as printed, a perfect camera and nothing in the way.
#[rustfmt::skip]
fn clean() -> Vec<Case> {
    vec![
        // Assorted poses and walls at HD.
        scene("cup-room", CUP, ROOM, [30., 20., 600.], [10., -5., 0.], 100.),
        scene("cat-room-tilt", CAT, ROOM, [-120., 40., 900.], [25., 0., 5.], 200.),
        scene("astro-dogs", ASTRO, DOGS, [-80., 30., 800.], [0., -20., 0.], 120.),
        scene("rocket-brushes", ROCKET, BRUSHES, [40., -20., 650.], [30., 0., 0.], 180.),
        scene("bowl-cups", BOWL, CUPS, [60., 0., 700.], [-15., 15., 0.], 150.),
        scene("hopper-boats-roll", HOPPER, BOATS, [0., 40., 500.], [5., 0., 30.], 90.),
        scene("cup-creek-roll", CUP, CREEK, [-50., -60., 1000.], [0., 35., 120.], 220.),
        scene("cat-cups-45", CAT, CUPS, [20., 10., 700.], [32., -32., 0.], 150.),
        // Size extremes and the edges of the view.
        scene("rocket-creek-small", ROCKET, CREEK, [-100., -80., 1000.], [-30., 0., 20.], 75.),
        scene("cat-dogs-large", CAT, DOGS, [0., 0., 450.], [0., -15., 0.], 240.),
        scene("cup-brushes-left", CUP, BRUSHES, [-250., 60., 480.], [0., 20., -10.], 80.),
        scene("hopper-room-bottom", HOPPER, ROOM, [100., 185., 500.], [20., 0., 0.], 70.),
        scene("astro-cups-corner", ASTRO, CUPS, [280., -185., 520.], [-10., -25., 170.], 80.),
        scene("cup-dogs-cut-top", CUP, DOGS, [40., -264., 600.], [10., 0., 5.], 150.),
        // Aspect changes and hand-eye transforms.
        scene("cup-boats-aspect", CUP, BOATS, [20., -30., 450.], [0., 8., 0.], 60.).stretch(1.4),
        scene("bowl-dogs-aspect", BOWL, DOGS, [-40., 50., 750.], [0., -30., -40.], 170.).stretch(0.7),
        scene("cat-cups-handeye", CAT, CUPS, [70., -30., 850.], [20., 0., -15.], 180.).hand_eye(),
        // The card's hue all around it: walls of that hue and painted patches.
        scene("bowl-marigold", BOWL, MARIGOLD, [-40., 20., 750.], [-10., 20., 15.], 160.),
        scene("cat-marigold", CAT, MARIGOLD, [20., -30., 550.], [0., 10., -60.], 120.),
        scene("bowl-room-patch", BOWL, ROOM, [80., -40., 700.], [15., -10., -25.], 140.)
            .paint(patch([1.5, 0.2], 1.6)),
        scene("hopper-cups-patches", HOPPER, CUPS, [-60., 30., 650.], [0., -25., 10.], 110.)
            .paint(patch([-1.3, 0.0], 1.0)).paint(patch([0.2, 1.3], 0.7)),
        scene("astro-creek-patch", ASTRO, CREEK, [30., 60., 800.], [-20., 0., 0.], 130.)
            .paint(patch([1.2, -0.6], 0.8)),
        // Small cards at FHD (the paper's setting).
        scene("cup-room-fhd", CUP, ROOM, [20., -10., 540.], [10., 10., 0.], 75.).fhd(),
        scene("cat-brushes-fhd", CAT, BRUSHES, [-60., 30., 650.], [-20., 0., 45.], 65.).fhd(),
        scene("bowl-cups-fhd", BOWL, CUPS, [40., 40., 750.], [0., 30., 0.], 55.).fhd(),
        scene("hopper-boats-fhd", HOPPER, BOATS, [100., -50., 600.], [25., 25., 0.], 70.).fhd(),
        scene("astro-dogs-fhd-edge", ASTRO, DOGS, [-280., 200., 540.], [0., 20., -30.], 60.).fhd(),
        scene("rocket-room-fhd-handeye", ROCKET, ROOM, [0., 50., 700.], [0., -25., 10.], 70.).fhd().hand_eye(),
        // Category level: the card differs from the photo the model was built from.
        scene("cup-dogs-recolour", CUP, DOGS, [-30., 20., 600.], [10., 15., 0.], 110.)
            .texture(Texture::Recolour { hue: 8.0, sat: 1.15 }),
        scene("cat-creek-recolour", CAT, CREEK, [50., -40., 700.], [-15., -10., 20.], 140.)
            .texture(Texture::Recolour { hue: -6.0, sat: 0.85 }),
        scene("bowl-dogs-fhd-recolour", BOWL, DOGS, [-30., -20., 620.], [0., 25., 0.], 70.).fhd()
            .texture(Texture::Recolour { hue: 10.0, sat: 1.2 }),
        scene("hopper-brushes-soft", HOPPER, BRUSHES, [20., -30., 650.], [0., 20., 0.], 120.)
            .texture(Texture::Blurred(2.0)),
        scene("rocket-marigold-recrop", ROCKET, MARIGOLD, [-20., 30., 800.], [20., 0., -10.], 170.)
            .texture(Texture::Recrop([8, -6, 10, 4])),
    ]
}

/// Scenes with noise, blur, other light, white balance or an occluder, and mixes.
#[rustfmt::skip]
fn hard() -> Vec<Case> {
    vec![
        scene("cup-room-noise-dim", CUP, ROOM, [50., 0., 650.], [12., 10., 0.], 110.).noise(8.0).light(0.7),
        scene("cat-dogs-occl-grey", CAT, DOGS, [-30., 20., 600.], [0., -20., 0.], 130.).occluded(0.2, GREY),
        scene("astro-cups-noise-occl", ASTRO, CUPS, [30., -20., 700.], [10., 15., 0.], 110.).noise(6.0)
            .occluded(0.15, GREEN).hand_eye(),
        scene("rocket-boats-bright", ROCKET, BOATS, [-60., 10., 800.], [-20., 10., 0.], 160.).noise(5.0).light(1.3),
        scene("bowl-creek-warm", BOWL, CREEK, [40., 30., 600.], [0., -20., 30.], 120.).wb(WARM),
        scene("hopper-marigold-cool", HOPPER, MARIGOLD, [-40., -20., 550.], [15., 15., 0.], 100.).wb(COOL).noise(4.0),
        scene("cup-brushes-defocus", CUP, BRUSHES, [0., 40., 700.], [-10., 20., 0.], 140.).blur(Blur::Defocus(1.2)),
        scene("cat-room-motion", CAT, ROOM, [60., -30., 750.], [20., -10., 10.], 150.)
            .blur(Blur::Motion(2.0, [1.0, 0.2])),
        scene("cup-cups-fhd-noise", CUP, CUPS, [-40., 20., 700.], [-15., 20., 0.], 60.).fhd().noise(6.0),
        scene("cat-room-fhd-defocus", CAT, ROOM, [60., -40., 600.], [20., 0., -20.], 70.).fhd()
            .blur(Blur::Defocus(1.5)),
        scene("bowl-boats-fhd-occl", BOWL, BOATS, [-50., 10., 560.], [0., 20., 10.], 75.).fhd().occluded(0.2, BLUE),
        scene("hopper-creek-fhd-warm-dim", HOPPER, CREEK, [30., 30., 650.], [-20., 10., 0.], 65.).fhd()
            .wb([1.1, 1.0, 0.9]).light(0.75),
        scene("astro-room-occl-red", ASTRO, ROOM, [-20., 40., 650.], [0., 30., -15.], 120.).occluded(0.25, RED),
        scene("rocket-dogs-motion-noise", ROCKET, DOGS, [80., -20., 700.], [-25., 0., 0.], 150.)
            .blur(Blur::Motion(1.5, [0.3, 1.0])).noise(5.0),
        scene("bowl-marigold-patch-noise", BOWL, MARIGOLD, [-60., -30., 650.], [10., -20., 0.], 130.)
            .paint(patch([-1.4, 0.3], 1.2)).noise(7.0).light(0.85),
        scene("hopper-cups-patch-occl", HOPPER, CUPS, [50., 20., 600.], [0., 25., 0.], 100.)
            .paint(patch([1.3, -0.2], 1.8)).occluded(0.15, GREY),
        scene("cup-creek-recolour-warm", CUP, CREEK, [-70., 10., 700.], [15., -15., 0.], 130.)
            .texture(Texture::Recolour { hue: -5.0, sat: 1.1 }).wb(WARM),
        scene("cat-brushes-bright-defocus", CAT, BRUSHES, [10., -50., 550.], [-20., 0., 40.], 110.).light(1.4)
            .blur(Blur::Defocus(1.0)),
        scene("astro-boats-small-noise", ASTRO, BOATS, [-60., 40., 1000.], [10., -15., 0.], 75.).noise(5.0),
        scene("astro-dogs-fhd-edge-noise", ASTRO, DOGS, [250., -180., 560.], [-20., -20., 0.], 65.).fhd().noise(10.0),
        scene("astro-creek-cut-bottom-noise", ASTRO, CREEK, [-60., 294., 650.], [-15., 10., 0.], 120.).noise(6.0),
        scene("rocket-room-everything", ROCKET, ROOM, [-30., 30., 700.], [30., -28., 20.], 150.).hand_eye().noise(6.0)
            .blur(Blur::Motion(1.5, [1.0, 1.0])).wb([1.1, 1.0, 0.9]).light(0.8).occluded(0.15, GREY),
        scene("cup-marigold-large-occl", CUP, MARIGOLD, [0., 10., 450.], [32., 32., 0.], 230.).occluded(0.25, ORANGE),
    ]
}
