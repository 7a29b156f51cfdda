//! The `[device]` sections of the configuration: which backend, and each backend's settings.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

/// Which device backend.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum DeviceKind {
    /// Simulated stylus and hand (closed loop, deterministic).
    Fake,
    /// A recorded session (`--record`).
    Replay,
    /// A HID device through hidapi (SpaceMouse-class input or a report-layout profile).
    Hid,
    /// A Touch/Phantom through the vendor's OpenHaptics HD library, loaded at run time.
    Openhaptics,
    /// A Force Dimension omega/delta/sigma (or a Novint Falcon through their SDK) through the
    /// vendor's DHD library (libdhd.so), loaded at run time.
    Dhd,
}

/// `[device]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DeviceSection {
    /// Backend.
    pub kind: DeviceKind,
    /// `[device.fake]`.
    pub fake: FakeSection,
    /// `[device.replay]`.
    pub replay: ReplaySection,
    /// `[device.hid]`.
    pub hid: HidSection,
    /// `[device.openhaptics]`.
    pub openhaptics: OpenHapticsSection,
    /// `[device.dhd]`.
    pub dhd: DhdSection,
}

impl Default for DeviceSection {
    fn default() -> Self {
        Self {
            kind: DeviceKind::Fake,
            fake: FakeSection::default(),
            replay: ReplaySection::default(),
            hid: HidSection::default(),
            openhaptics: OpenHapticsSection::default(),
            dhd: DhdSection::default(),
        }
    }
}

/// `[device.fake]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FakeSection {
    /// `idle`, `circle`, `line`, `press` or `file`.
    pub path: String,
    /// Path file for `path = "file"` (lines `t_s x y z [buttons]`).
    pub path_file: Option<PathBuf>,
    /// Tremor seed.
    pub seed: u64,
    /// Circle radius / line half-length / press depth, m.
    pub size_m: f32,
    /// Seconds per circle, line stroke or press cycle.
    pub period_s: f32,
    /// Tremor amplitude, m.
    pub tremor_m: f32,
    /// Where the force really acts, as a signed axis permutation (`"x,y,z"`: correct;
    /// `"-x,z,y"`: +x comes out as −x, y and z swapped), to try `check --force-test` on.
    pub axes: String,
}

impl Default for FakeSection {
    fn default() -> Self {
        Self {
            path: "circle".into(),
            path_file: None,
            seed: 1,
            size_m: 0.02,
            period_s: 4.0,
            tremor_m: 2e-5,
            axes: "x,y,z".into(),
        }
    }
}

/// `[device.replay]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(default, deny_unknown_fields)]
pub struct ReplaySection {
    /// The recording to play.
    pub file: Option<PathBuf>,
    /// Start again at the end.
    #[serde(rename = "loop")]
    pub looped: bool,
}

/// `[device.hid]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct HidSection {
    /// `spacemouse` or `layout`.
    pub profile: String,
    /// Report-layout file for `profile = "layout"`.
    pub layout_file: Option<PathBuf>,
    /// USB vendor id (omit: the first matching device).
    pub vendor_id: Option<u16>,
    /// USB product id.
    pub product_id: Option<u16>,
}

impl Default for HidSection {
    fn default() -> Self {
        Self {
            profile: "spacemouse".into(),
            layout_file: None,
            vendor_id: None,
            product_id: None,
        }
    }
}

/// `[device.openhaptics]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct OpenHapticsSection {
    /// The HD library to load (a name searched by the dynamic loader, or a path).
    pub library: String,
    /// Device name passed to `hdInitDevice` (empty: the default device).
    pub device_name: String,
}

impl Default for OpenHapticsSection {
    fn default() -> Self {
        Self {
            library: "libHD.so".into(),
            device_name: String::new(),
        }
    }
}

/// `[device.dhd]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DhdSection {
    /// The DHD library to load (a name searched by the dynamic loader, or a path).
    pub library: String,
    /// Which attached Force Dimension device, 0-based (`dhdOpenID`); omit: the first
    /// (`dhdOpen`).
    pub index: Option<u8>,
}

impl Default for DhdSection {
    fn default() -> Self {
        Self {
            library: "libdhd.so".into(),
            index: None,
        }
    }
}
