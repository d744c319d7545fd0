//! Finding the ZED in sysfs and its factory calibration on disk.
//!
//! A UVC camera's video node `/sys/class/video4linux/videoN` links (`device`) to its USB
//! interface, whose `modalias` names the USB vendor and product
//! (`usb:v2B03pF880d0100dcEFdsc02dp01ic0Eisc01ip00in00`); the USB device above the
//! interface holds `serial` and `speed` (Mb/s). The ZED's serial number is its USB serial
//! string, or, where the video function does not carry it, that of its sensor module, a
//! Stereolabs sibling on the camera's internal hub. Its calibration is `SN<serial>.conf`
//! where the ZED tools put it: `/usr/local/zed/settings/` or `~/zed/settings/`.

use std::path::{Path, PathBuf};

/// USB vendor of Stereolabs.
pub const ZED_VENDOR: u16 = 0x2b03;
/// USB product of the ZED 2i's video function.
pub const ZED_2I_PRODUCT: u16 = 0xf880;
/// Where the ZED tools keep factory calibration files, besides `~/zed/settings/`.
pub const SYSTEM_SETTINGS: &str = "/usr/local/zed/settings";

/// Vendor and product of a USB function.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct UsbId {
    /// USB vendor id (0x2b03 for Stereolabs).
    pub vendor: u16,
    /// USB product id.
    pub product: u16,
}

/// The USB id in a sysfs `modalias` (`usb:vVVVVpPPPP…`); `None` for other buses or
/// damaged text.
pub fn parse_modalias(text: &str) -> Option<UsbId> {
    let rest = text.trim().strip_prefix("usb:v")?;
    let hex = |s: Option<&str>| {
        let s = s?;
        s.bytes()
            .all(|b| b.is_ascii_hexdigit())
            .then(|| u16::from_str_radix(s, 16).ok())?
    };
    let vendor = hex(rest.get(..4))?;
    let product = hex(rest.get(4..)?.strip_prefix('p')?.get(..4))?;
    Some(UsbId { vendor, product })
}

/// The camera's name for logs: `ZED 2i`, or the Stereolabs product id.
pub fn product_name(product: u16) -> String {
    match product {
        ZED_2I_PRODUCT => "ZED 2i".into(),
        other => format!("Stereolabs camera 0x{other:04x}"),
    }
}

/// A ZED video node found in sysfs.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Camera {
    /// `/dev/videoN`.
    pub node: PathBuf,
    /// The USB function's vendor and product.
    pub id: UsbId,
    /// The camera's serial number, when sysfs has it.
    pub serial: Option<String>,
    /// USB link speed, Mb/s (480: USB 2, 5000 and up: USB 3).
    pub usb_speed_mbps: Option<u32>,
}

/// Finding a camera or its calibration failed.
#[derive(Debug, thiserror::Error)]
pub enum DiscoveryError {
    /// No video device of vendor 0x2b03 in sysfs.
    #[error("no ZED camera found: no video device in {} has USB vendor 0x2b03 (is it plugged in? `lsusb -d 2b03:` lists it); or pass --device /dev/videoN", .dir.display())]
    NoCamera {
        /// The sysfs directory of video devices searched.
        dir: PathBuf,
    },
    /// sysfs has no serial number, so the calibration file is unknown.
    #[error("cannot read the camera's serial number from sysfs, so its calibration file is unknown: set [camera] calibration in a --config file to its SN<serial>.conf (the ZED tools keep it in {})", dir_list(.dirs))]
    NoSerial {
        /// Where the ZED tools keep calibration files.
        dirs: Vec<PathBuf>,
    },
    /// The camera's `SN<serial>.conf` is in none of the calibration directories.
    #[error("no SN{serial}.conf in {}: download it from https://calib.stereolabs.com/?SN={serial} into one of them, or set [camera] calibration in a --config file", dir_list(.dirs))]
    NoCalibration {
        /// The camera's serial number.
        serial: String,
        /// The directories searched.
        dirs: Vec<PathBuf>,
    },
}

fn dir_list(dirs: &[PathBuf]) -> String {
    let names: Vec<String> = dirs.iter().map(|d| format!("{}/", d.display())).collect();
    names.join(" or ")
}

/// The sysfs tree (`/` on a running system; a copy in tests).
#[derive(Debug, Clone)]
pub struct Sysfs {
    root: PathBuf,
}

impl Default for Sysfs {
    fn default() -> Self {
        Self::new("/")
    }
}

impl Sysfs {
    /// The tree under `root` (`root/sys/class/video4linux`, `root/dev`).
    pub fn new(root: impl Into<PathBuf>) -> Self {
        Self { root: root.into() }
    }

    fn class_dir(&self) -> PathBuf {
        self.root.join("sys/class/video4linux")
    }

    /// The first Stereolabs capture node (lowest `videoN`); other Stereolabs products
    /// than the ZED 2i are accepted (the caller warns).
    pub fn find_zed(&self) -> Result<Camera, DiscoveryError> {
        let dir = self.class_dir();
        let mut names: Vec<(u32, String)> = std::fs::read_dir(&dir)
            .into_iter()
            .flatten()
            .flatten()
            .filter_map(|e| {
                let name = e.file_name().to_string_lossy().into_owned();
                Some((name.strip_prefix("video")?.parse().ok()?, name))
            })
            .collect();
        names.sort();
        names
            .iter()
            .filter_map(|(_, name)| self.camera(name))
            .find(|c| c.id.vendor == ZED_VENDOR)
            .ok_or(DiscoveryError::NoCamera { dir })
    }

    /// What sysfs says about `/dev/videoN` (`None` when it is no USB video capture node).
    pub fn describe(&self, node: &Path) -> Option<Camera> {
        self.camera(node.file_name()?.to_str()?)
    }

    /// The capture node `name` (`videoN`): its USB id, serial and speed. UVC cameras
    /// also have a metadata node (`index` 1), which is skipped.
    fn camera(&self, name: &str) -> Option<Camera> {
        let node_dir = self.class_dir().join(name);
        let read = |p: &Path| std::fs::read_to_string(p).ok().map(|s| s.trim().to_string());
        if read(&node_dir.join("index")).is_some_and(|i| i != "0") {
            return None;
        }
        let interface = node_dir.join("device");
        let id = parse_modalias(&read(&interface.join("modalias"))?)?;
        let usb = std::fs::canonicalize(&interface).ok()?.parent()?.to_path_buf();
        let serial = read(&usb.join("serial"))
            .filter(|s| is_serial(s))
            .or_else(|| sibling_serial(&usb));
        Some(Camera {
            node: self.root.join("dev").join(name),
            id,
            serial,
            usb_speed_mbps: read(&usb.join("speed"))
                .and_then(|s| s.parse::<f64>().ok())
                .map(|s| s as u32),
        })
    }
}

/// A ZED serial number: decimal digits.
fn is_serial(s: &str) -> bool {
    !s.is_empty() && s.len() <= 12 && s.bytes().all(|b| b.is_ascii_digit())
}

/// The serial of another Stereolabs USB device on the same hub as `usb` (the ZED's
/// sensor module).
fn sibling_serial(usb: &Path) -> Option<String> {
    let mut siblings: Vec<PathBuf> = std::fs::read_dir(usb.parent()?)
        .ok()?
        .flatten()
        .map(|e| e.path())
        .filter(|p| p != usb)
        .collect();
    siblings.sort();
    siblings.iter().find_map(|p| {
        let vendor = std::fs::read_to_string(p.join("idVendor")).ok()?;
        if u16::from_str_radix(vendor.trim(), 16).ok()? != ZED_VENDOR {
            return None;
        }
        let serial = std::fs::read_to_string(p.join("serial")).ok()?;
        is_serial(serial.trim()).then(|| serial.trim().to_string())
    })
}

/// Where factory calibrations are looked for: `/usr/local/zed/settings` and, with a
/// home directory, `~/zed/settings`.
pub fn calibration_dirs(home: Option<&Path>) -> Vec<PathBuf> {
    let mut dirs = vec![PathBuf::from(SYSTEM_SETTINGS)];
    dirs.extend(home.map(|h| h.join("zed/settings")));
    dirs
}

/// The calibration file of the camera: `explicit` (`[camera] calibration`) when given,
/// else `SN<serial>.conf` in the first of `dirs` that has it.
pub fn find_calibration(
    explicit: Option<&Path>,
    serial: Option<&str>,
    dirs: &[PathBuf],
) -> Result<PathBuf, DiscoveryError> {
    if let Some(path) = explicit {
        return Ok(path.to_path_buf());
    }
    let Some(serial) = serial else {
        return Err(DiscoveryError::NoSerial { dirs: dirs.to_vec() });
    };
    let file = format!("SN{serial}.conf");
    dirs.iter()
        .map(|d| d.join(&file))
        .find(|p| p.is_file())
        .ok_or_else(|| DiscoveryError::NoCalibration {
            serial: serial.to_string(),
            dirs: dirs.to_vec(),
        })
}

/// A fake sysfs tree for tests: [`SysfsTree::usb`] adds a USB device and its video nodes.
#[derive(Debug)]
pub struct SysfsTree {
    /// The tree's root, standing in for `/sys`.
    pub root: PathBuf,
}

impl SysfsTree {
    /// An empty tree at `root` (removed first).
    pub fn new(root: &Path) -> std::io::Result<Self> {
        let _ = std::fs::remove_dir_all(root);
        std::fs::create_dir_all(root.join("sys/class/video4linux"))?;
        Ok(Self {
            root: root.to_path_buf(),
        })
    }

    /// Adds USB device `port` (`1-2`) with the attributes `attrs` (`serial`, `speed`,
    /// `idVendor`, …) and, when `video` is given, its video nodes: `(name, index,
    /// modalias)` under interface `port:1.0`.
    pub fn usb(&self, port: &str, attrs: &[(&str, &str)], video: &[(&str, u32, &str)]) -> std::io::Result<()> {
        let usb = self.root.join("sys/devices/pci0000:00/0000:00:14.0/usb2").join(port);
        let interface = usb.join(format!("{port}:1.0"));
        std::fs::create_dir_all(&interface)?;
        for (name, value) in attrs {
            std::fs::write(usb.join(name), format!("{value}\n"))?;
        }
        for (name, index, modalias) in video {
            std::fs::write(interface.join("modalias"), format!("{modalias}\n"))?;
            let node = self.root.join("sys/class/video4linux").join(name);
            std::fs::create_dir_all(&node)?;
            std::fs::write(node.join("index"), format!("{index}\n"))?;
            std::os::unix::fs::symlink(&interface, node.join("device"))?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The modalias of a ZED 2i's video interface, as sysfs shows it.
    const ZED_2I: &str = "usb:v2B03pF880d0100dcEFdsc02dp01ic0Eisc01ip00in00";

    fn tree(name: &str) -> SysfsTree {
        let dir = std::env::temp_dir().join(format!("photopose-sysfs-{name}-{}", std::process::id()));
        SysfsTree::new(&dir).unwrap()
    }

    #[test]
    fn modalias_strings_parse() {
        assert_eq!(
            parse_modalias(ZED_2I),
            Some(UsbId {
                vendor: 0x2b03,
                product: 0xf880
            })
        );
        // A laptop webcam, lower-case hex, trailing newline.
        assert_eq!(
            parse_modalias("usb:v04F2pB6D9d0011dcEFdsc02dp01ic0Eisc01ip00in00\n"),
            Some(UsbId {
                vendor: 0x04f2,
                product: 0xb6d9
            })
        );
        assert_eq!(
            parse_modalias("usb:v2b03pf780d0100dcEF"),
            Some(UsbId {
                vendor: 0x2b03,
                product: 0xf780
            })
        );
        for bad in [
            "pci:v00008086d00009A19sv00001028sd00000A23bc04sc80i00",
            "platform:vivid",
            "usb:v2B0",
            "usb:v2B03",
            "usb:v2B03xF880",
            "usb:vZZZZpF880",
            "",
        ] {
            assert_eq!(parse_modalias(bad), None, "{bad}");
        }
        assert_eq!(product_name(0xf880), "ZED 2i");
        assert_eq!(product_name(0xf582), "Stereolabs camera 0xf582");
    }

    #[test]
    fn the_zed_capture_node_is_found_with_serial_and_speed() {
        let t = tree("find");
        // A webcam first, then the ZED with its metadata node.
        let webcam = "usb:v04F2pB6D9d0011dcEFdsc02dp01ic0Eisc01ip00in00";
        t.usb("1-1", &[("serial", "0001"), ("speed", "480")], &[("video0", 0, webcam)])
            .unwrap();
        t.usb(
            "2-1.1",
            &[("idVendor", "2b03"), ("serial", "OV0001"), ("speed", "5000")],
            &[("video2", 0, ZED_2I), ("video3", 1, ZED_2I)],
        )
        .unwrap();
        // The sensor module on the camera's hub carries the serial number.
        t.usb(
            "2-1.2",
            &[("idVendor", "2b03"), ("idProduct", "f881"), ("serial", "38123456")],
            &[],
        )
        .unwrap();
        let sys = Sysfs::new(&t.root);
        let cam = sys.find_zed().unwrap();
        assert_eq!(cam.node, t.root.join("dev/video2"));
        assert_eq!((cam.id.vendor, cam.id.product), (0x2b03, 0xf880));
        assert_eq!(cam.serial.as_deref(), Some("38123456"));
        assert_eq!(cam.usb_speed_mbps, Some(5000));
        // --device names a node: described the same way; the webcam is no ZED.
        assert_eq!(sys.describe(Path::new("/dev/video2")), Some(cam));
        assert_eq!(sys.describe(Path::new("/dev/video0")).unwrap().id.vendor, 0x04f2);
        assert_eq!(sys.describe(Path::new("/dev/video3")), None);
        assert_eq!(sys.describe(Path::new("/dev/video99")), None);
        std::fs::remove_dir_all(&t.root).unwrap();
    }

    #[test]
    fn a_numeric_usb_serial_is_the_cameras_own() {
        let t = tree("serial");
        t.usb(
            "3-2",
            &[("serial", "25123456"), ("speed", "480")],
            &[("video0", 0, ZED_2I)],
        )
        .unwrap();
        let cam = Sysfs::new(&t.root).find_zed().unwrap();
        assert_eq!(
            (cam.serial.as_deref(), cam.usb_speed_mbps),
            (Some("25123456"), Some(480))
        );
        std::fs::remove_dir_all(&t.root).unwrap();
    }

    #[test]
    fn no_camera_says_where_it_looked() {
        let t = tree("none");
        let e = Sysfs::new(&t.root).find_zed().unwrap_err().to_string();
        assert!(
            e.contains("no ZED camera found") && e.contains("0x2b03") && e.contains("--device"),
            "{e}"
        );
        assert!(Sysfs::new(t.root.join("missing")).find_zed().is_err());
        std::fs::remove_dir_all(&t.root).unwrap();
    }

    #[test]
    fn calibration_is_found_by_serial_or_explained() {
        let t = tree("calib");
        let (system, home) = (t.root.join("usr/local/zed/settings"), t.root.join("home/me"));
        std::fs::create_dir_all(&system).unwrap();
        std::fs::create_dir_all(home.join("zed/settings")).unwrap();
        std::fs::write(home.join("zed/settings/SN38123456.conf"), "").unwrap();
        std::fs::write(system.join("SN111.conf"), "").unwrap();
        std::fs::write(home.join("zed/settings/SN111.conf"), "").unwrap();
        let dirs = vec![system.clone(), home.join("zed/settings")];
        assert_eq!(
            calibration_dirs(Some(Path::new("/home/me"))),
            [
                PathBuf::from("/usr/local/zed/settings"),
                PathBuf::from("/home/me/zed/settings")
            ]
        );
        assert_eq!(
            find_calibration(None, Some("38123456"), &dirs).unwrap(),
            home.join("zed/settings/SN38123456.conf")
        );
        // The system directory comes first.
        assert_eq!(
            find_calibration(None, Some("111"), &dirs).unwrap(),
            system.join("SN111.conf")
        );
        // An explicit file wins, serial or not.
        let mine = Path::new("my.conf");
        assert_eq!(find_calibration(Some(mine), None, &dirs).unwrap(), mine);
        let e = find_calibration(None, Some("222"), &dirs).unwrap_err().to_string();
        assert!(
            e.starts_with("no SN222.conf in ")
                && e.contains(&format!("{}/ or ", system.display()))
                && e.contains("https://calib.stereolabs.com/?SN=222")
                && e.contains("[camera] calibration"),
            "{e}"
        );
        let e = find_calibration(None, None, &dirs).unwrap_err().to_string();
        assert!(
            e.contains("serial number") && e.contains("[camera] calibration") && e.contains("zed/settings/"),
            "{e}"
        );
        std::fs::remove_dir_all(&t.root).unwrap();
    }
}
