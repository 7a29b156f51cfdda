//! `haptics-server devices`: what is attached, which backend would drive it, and why it
//! cannot be opened when it cannot.
//!
//! Three sources: HID devices through hidapi (`/dev/hidraw*`), USB devices of known haptic
//! vendors from sysfs (`/sys/bus/usb/devices/*`: Force Dimension and the Novint Falcon, which
//! the vendor's DHD library opens through `/dev/bus/usb`, and 3D Systems' Touch, whose
//! serial port `/dev/ttyACM*` `libHD` opens), and the vendor libraries (does each load, from
//! which file, with every function; if not, which names were looked for and where). Each
//! device node is checked for read/write access as the current user (`access(2)`), and a
//! refusal names the udev rules that grant it. Scanning takes a sysfs root so tests can give
//! it a tree of their own.

use std::os::unix::fs::{MetadataExt, PermissionsExt};
use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::device::{dhd, openhaptics};

/// The udev rules shipped with the server.
pub const RULES: &str = "deploy/70-haptics.rules";

/// A vendor (and optionally products) the server knows a backend for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct KnownVendor {
    /// USB vendor id.
    pub vendor_id: u16,
    /// Only these products (`None`: all of the vendor's).
    pub products: Option<&'static [u16]>,
    /// Who makes it.
    pub name: &'static str,
    /// The `--device` value that drives it.
    pub backend: &'static str,
    /// How, in a few words.
    pub how: &'static str,
    /// `deploy/70-haptics.rules` grants its nodes to the `haptics` group.
    pub in_rules: bool,
}

/// 3Dconnexion devices that carry Logitech's vendor id (as in `deploy/70-haptics.rules`).
pub const SPACEMOUSE_LOGITECH_PRODUCTS: [u16; 12] = [
    0xc603, 0xc605, 0xc606, 0xc621, 0xc623, 0xc625, 0xc626, 0xc627, 0xc628, 0xc629, 0xc62b, 0xc640,
];

/// Every vendor `devices` recognises.
pub const KNOWN: [KnownVendor; 5] = [
    KnownVendor {
        vendor_id: 0x256f,
        products: None,
        name: "3Dconnexion",
        backend: "hid",
        how: "--device hid (spacemouse profile: a 6-DOF cursor, no force)",
        in_rules: true,
    },
    KnownVendor {
        vendor_id: 0x046d,
        products: Some(&SPACEMOUSE_LOGITECH_PRODUCTS),
        name: "3Dconnexion (Logitech vendor id)",
        backend: "hid",
        how: "--device hid (spacemouse profile: a 6-DOF cursor, no force)",
        in_rules: true,
    },
    KnownVendor {
        vendor_id: 0x2988,
        products: None,
        name: "3D Systems (Touch, Phantom)",
        backend: "openhaptics",
        how: "--device openhaptics (libHD opens its serial port); a HID interface: --device hid \
              with a report layout",
        in_rules: true,
    },
    KnownVendor {
        vendor_id: 0x1451,
        products: None,
        name: "Force Dimension (omega, delta, sigma, lambda)",
        backend: "dhd",
        how: "--device dhd (libdhd.so opens it through /dev/bus/usb)",
        in_rules: true,
    },
    KnownVendor {
        vendor_id: 0x0403,
        products: Some(&[0xcb48]),
        name: "Novint Falcon",
        backend: "dhd",
        how: "--device dhd (Force Dimension's SDK drives the Falcon)",
        in_rules: true,
    },
];

/// The known vendor entry for `vendor_id:product_id`.
pub fn known(vendor_id: u16, product_id: u16) -> Option<&'static KnownVendor> {
    KNOWN
        .iter()
        .find(|k| k.vendor_id == vendor_id && k.products.is_none_or(|p| p.contains(&product_id)))
}

/// Whether the current user may open a device node, and if not, why and what to do.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Access {
    /// The node.
    pub node: PathBuf,
    /// Read and write are allowed.
    pub ok: bool,
    /// Owner, group, mode; and the fix when refused.
    pub detail: String,
}

/// The udev line that would grant `vendor_id`'s USB nodes to the `haptics` group.
pub fn usb_rule(vendor_id: u16, product_id: Option<u16>) -> String {
    let product = product_id.map_or(String::new(), |p| {
        format!(r#" ATTRS{{idProduct}}=="{p:04x}","#)
    });
    format!(
        r#"SUBSYSTEM=="usb", ATTRS{{idVendor}}=="{vendor_id:04x}",{product} GROUP="haptics", MODE="0660", TAG+="uaccess""#
    )
}

/// Check `node` for read/write access; `rule` is what to install when refused (`None`: the
/// shipped rules cover it).
pub fn access(node: &Path, rule: Option<&str>) -> Access {
    let Ok(meta) = std::fs::metadata(node) else {
        return Access {
            node: node.into(),
            ok: false,
            detail: format!(
                "{} does not exist (unplugged, or the driver has not created it)",
                node.display()
            ),
        };
    };
    let owner = format!(
        "{} {}:{}",
        mode_string(meta.permissions().mode()),
        user_name(meta.uid()),
        group_name(meta.gid())
    );
    let c = std::ffi::CString::new(node.as_os_str().as_encoded_bytes()).unwrap_or_default();
    // SAFETY: `c` is a valid NUL-terminated path; access(2) only reads it.
    let ok = unsafe { libc::access(c.as_ptr(), libc::R_OK | libc::W_OK) } == 0;
    let detail = if ok {
        format!("{owner}: this user may open it")
    } else {
        let fix = match rule {
            None => format!(
                "install {RULES} (sudo install -m 0644 {RULES} /etc/udev/rules.d/ && sudo udevadm \
                 control --reload && sudo udevadm trigger), join the group (sudo usermod -aG \
                 haptics $USER, then log in again), then replug"
            ),
            Some(rule) => format!(
                "{RULES} does not cover this device yet: add the line `{rule}` to \
                 /etc/udev/rules.d/70-haptics.rules (sudo udevadm control --reload && sudo \
                 udevadm trigger), join the haptics group (sudo usermod -aG haptics $USER, log \
                 in again), then replug"
            ),
        };
        format!("{owner}: permission denied for this user; {fix}")
    };
    Access {
        node: node.into(),
        ok,
        detail,
    }
}

fn mode_string(mode: u32) -> String {
    let bits = [
        (0o400, 'r'),
        (0o200, 'w'),
        (0o100, 'x'),
        (0o040, 'r'),
        (0o020, 'w'),
        (0o010, 'x'),
        (0o004, 'r'),
        (0o002, 'w'),
        (0o001, 'x'),
    ];
    bits.iter()
        .map(|&(b, c)| if mode & b != 0 { c } else { '-' })
        .collect()
}

fn name_from(file: &str, id: u32) -> String {
    std::fs::read_to_string(file)
        .ok()
        .and_then(|t| {
            t.lines().find_map(|l| {
                let f: Vec<&str> = l.split(':').collect();
                (f.len() > 2 && f[2] == id.to_string()).then(|| f[0].to_owned())
            })
        })
        .unwrap_or_else(|| id.to_string())
}

fn user_name(uid: u32) -> String {
    name_from("/etc/passwd", uid)
}

fn group_name(gid: u32) -> String {
    name_from("/etc/group", gid)
}

/// One HID device.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct HidEntry {
    /// `vvvv:pppp`.
    pub id: String,
    /// Product string.
    pub product: String,
    /// Manufacturer string.
    pub manufacturer: String,
    /// The known vendor, if any.
    pub vendor: Option<String>,
    /// The backend that drives it, and how.
    pub backend: Option<String>,
    /// Access to its node.
    pub access: Access,
}

/// One USB device of a known vendor, found in sysfs.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct UsbEntry {
    /// `vvvv:pppp`.
    pub id: String,
    /// Product string (sysfs `product`).
    pub product: String,
    /// The vendor.
    pub vendor: String,
    /// The backend that drives it, and how.
    pub backend: String,
    /// Access to the node the backend opens (`/dev/bus/usb/BBB/DDD`, or `/dev/ttyACMn`).
    pub access: Vec<Access>,
}

/// A vendor library.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LibraryEntry {
    /// `openhaptics` or `dhd`.
    pub backend: String,
    /// The configured name or path.
    pub requested: String,
    /// It loads with every required function.
    pub ok: bool,
    /// The file it loaded from.
    pub path: Option<PathBuf>,
    /// What else: SDK version and devices counted, optional functions missing, or why it
    /// does not load.
    pub detail: String,
}

/// Everything `devices` found.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Inventory {
    /// HID devices (known vendors only unless `all`).
    pub hid: Vec<HidEntry>,
    /// HID devices of other vendors left out (see `--all`).
    pub hid_hidden: usize,
    /// Why HID devices could not be listed.
    pub hid_error: Option<String>,
    /// USB devices of known vendors not listed as HID.
    pub usb: Vec<UsbEntry>,
    /// The vendor libraries.
    pub libraries: Vec<LibraryEntry>,
}

/// List HID devices; `all` keeps those of unknown vendors.
pub fn hid_devices(all: bool) -> Result<(Vec<HidEntry>, usize), String> {
    let api = hidapi::HidApi::new().map_err(|e| e.to_string())?;
    let mut out = Vec::new();
    let mut hidden = 0;
    for d in api.device_list() {
        let k = known(d.vendor_id(), d.product_id());
        if k.is_none() && !all {
            hidden += 1;
            continue;
        }
        let node = PathBuf::from(d.path().to_string_lossy().into_owned());
        let entry = HidEntry {
            id: format!("{:04x}:{:04x}", d.vendor_id(), d.product_id()),
            product: d.product_string().unwrap_or("?").to_owned(),
            manufacturer: d.manufacturer_string().unwrap_or("?").to_owned(),
            vendor: k.map(|k| k.name.to_owned()),
            backend: Some(k.map_or_else(
                || {
                    "not a known haptic device: --device hid with a report layout if it is one"
                        .into()
                },
                |k| k.how.to_owned(),
            )),
            access: access(
                &node,
                k.filter(|k| !k.in_rules)
                    .map(|k| usb_rule(k.vendor_id, None))
                    .as_deref(),
            ),
        };
        if !out
            .iter()
            .any(|e: &HidEntry| e.access.node == entry.access.node)
        {
            out.push(entry);
        }
    }
    Ok((out, hidden))
}

fn read_trim(p: &Path) -> Option<String> {
    std::fs::read_to_string(p).ok().map(|s| s.trim().to_owned())
}

/// USB devices of the known non-HID vendors (Force Dimension, Falcon, 3D Systems' serial
/// Touch) under `sys_root` (`/` normally), with the nodes under `dev_root` (`/dev`).
pub fn usb_devices(sys_root: &Path, dev_root: &Path) -> Vec<UsbEntry> {
    let base = sys_root.join("sys/bus/usb/devices");
    let mut dirs: Vec<PathBuf> = std::fs::read_dir(&base)
        .into_iter()
        .flatten()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.join("idVendor").exists())
        .collect();
    dirs.sort();
    let mut out = Vec::new();
    for dir in dirs {
        let hex = |f: &str| read_trim(&dir.join(f)).and_then(|s| u16::from_str_radix(&s, 16).ok());
        let (Some(vid), Some(pid)) = (hex("idVendor"), hex("idProduct")) else {
            continue;
        };
        let Some(k) = known(vid, pid) else { continue };
        if k.backend == "hid" {
            continue; // listed through hidapi
        }
        let mut nodes = Vec::new();
        if k.backend == "openhaptics" {
            // The Touch's serial port: <interface>/tty/ttyACMn.
            for iface in std::fs::read_dir(&dir).into_iter().flatten().flatten() {
                for tty in std::fs::read_dir(iface.path().join("tty"))
                    .into_iter()
                    .flatten()
                    .flatten()
                {
                    nodes.push(dev_root.join(tty.file_name()));
                }
            }
        } else {
            let num = |f: &str| read_trim(&dir.join(f)).and_then(|s| s.parse::<u32>().ok());
            if let (Some(bus), Some(dev)) = (num("busnum"), num("devnum")) {
                nodes.push(dev_root.join(format!("bus/usb/{bus:03}/{dev:03}")));
            }
        }
        nodes.sort();
        let rule = (!k.in_rules).then(|| usb_rule(vid, k.products.map(|_| pid)));
        out.push(UsbEntry {
            id: format!("{vid:04x}:{pid:04x}"),
            product: read_trim(&dir.join("product")).unwrap_or_else(|| "?".into()),
            vendor: k.name.into(),
            backend: k.how.into(),
            access: nodes.iter().map(|n| access(n, rule.as_deref())).collect(),
        });
    }
    out
}

/// Probe both vendor libraries by the configured names or paths.
pub fn libraries(openhaptics_lib: &str, dhd_lib: &str) -> Vec<LibraryEntry> {
    let oh = match openhaptics::probe(openhaptics_lib) {
        Ok(()) => LibraryEntry {
            backend: "openhaptics".into(),
            requested: openhaptics_lib.into(),
            ok: true,
            path: openhaptics::loaded_path(openhaptics_lib),
            detail: "loads and exports every function the backend needs".into(),
        },
        Err(e) => LibraryEntry {
            backend: "openhaptics".into(),
            requested: openhaptics_lib.into(),
            ok: false,
            path: None,
            detail: e.to_string(),
        },
    };
    let dhd = match dhd::probe(dhd_lib) {
        Ok(lib) => {
            let mut detail = "loads and exports every function the backend needs".to_owned();
            if let Some(v) = lib.sdk_version() {
                detail.push_str(&format!("; SDK {v}"));
            }
            match lib.device_count() {
                Some(0) => detail.push_str(
                    "; dhdGetDeviceCount() = 0: no Force Dimension device attached and powered \
                     (or not accessible: see the USB list)",
                ),
                Some(n) => detail.push_str(&format!("; dhdGetDeviceCount() = {n}")),
                None => {}
            }
            let missing = lib.missing_optional();
            if !missing.is_empty() {
                detail.push_str(&format!(
                    "; without the optional {} (older SDK: orientation or velocity are \
                     estimated or identity)",
                    missing.join(", ")
                ));
            }
            LibraryEntry {
                backend: "dhd".into(),
                requested: dhd_lib.into(),
                ok: true,
                path: lib.path(),
                detail,
            }
        }
        Err(e) => LibraryEntry {
            backend: "dhd".into(),
            requested: dhd_lib.into(),
            ok: false,
            path: None,
            detail: e.to_string(),
        },
    };
    vec![oh, dhd]
}

/// Everything at once.
pub fn scan(all: bool, openhaptics_lib: &str, dhd_lib: &str) -> Inventory {
    let (hid, hid_hidden, hid_error) = match hid_devices(all) {
        Ok((h, n)) => (h, n, None),
        Err(e) => (Vec::new(), 0, Some(e)),
    };
    Inventory {
        hid,
        hid_hidden,
        hid_error,
        usb: usb_devices(Path::new("/"), Path::new("/dev")),
        libraries: libraries(openhaptics_lib, dhd_lib),
    }
}

impl Inventory {
    /// The readable listing.
    pub fn summary(&self) -> String {
        use std::fmt::Write as _;
        let mut s = String::new();
        let _ = writeln!(
            s,
            "fake: always available (simulated stylus: --device fake)"
        );
        let _ = writeln!(
            s,
            "replay: plays a --record file (--device replay --replay-file FILE)"
        );
        match (&self.hid_error, self.hid.is_empty()) {
            (Some(e), _) => {
                let _ = writeln!(s, "hid: cannot enumerate HID devices: {e}");
            }
            (None, true) => {
                let _ = writeln!(
                    s,
                    "hid: no HID device of a known vendor attached{}",
                    hidden_note(self.hid_hidden)
                );
            }
            (None, false) => {
                let _ = writeln!(s, "hid:{}", hidden_note(self.hid_hidden));
                for d in &self.hid {
                    let _ = writeln!(
                        s,
                        "  {}  {} ({}){}\n    backend: {}\n    {} {}",
                        d.id,
                        d.product,
                        d.manufacturer,
                        d.vendor
                            .as_deref()
                            .map_or(String::new(), |v| format!(" [{v}]")),
                        d.backend.as_deref().unwrap_or("?"),
                        if d.access.ok { "ok  " } else { "DENY" },
                        d.access.detail
                    );
                }
            }
        }
        if self.usb.is_empty() {
            let _ = writeln!(
                s,
                "usb: no Force Dimension, Novint Falcon or 3D Systems (serial Touch) device attached"
            );
        } else {
            let _ = writeln!(s, "usb:");
            for d in &self.usb {
                let _ = writeln!(
                    s,
                    "  {}  {} [{}]\n    backend: {}",
                    d.id, d.product, d.vendor, d.backend
                );
                if d.access.is_empty() {
                    let _ = writeln!(s, "    no device node found for it in sysfs");
                }
                for a in &d.access {
                    let _ = writeln!(s, "    {} {}", if a.ok { "ok  " } else { "DENY" }, a.detail);
                }
            }
        }
        for l in &self.libraries {
            let _ = writeln!(
                s,
                "{}: {} {}\n    {}",
                l.backend,
                l.requested,
                match (&l.path, l.ok) {
                    (Some(p), true) => format!("loads from {}", p.display()),
                    (None, true) => "loads".into(),
                    (_, false) => "DOES NOT LOAD".into(),
                },
                l.detail
            );
        }
        s
    }

    /// Pretty JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_else(|e| format!("{{\"error\":\"{e}\"}}"))
    }
}

fn hidden_note(n: usize) -> String {
    if n == 0 {
        String::new()
    } else {
        format!(" ({n} HID devices of other vendors not shown; --all lists them)")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(p: &Path, text: &str) {
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(p, text).unwrap();
    }

    #[test]
    fn known_usb_devices_are_found_in_sysfs_with_their_nodes() {
        let root = tempfile::tempdir().unwrap();
        let sys = root.path().join("sys/bus/usb/devices");
        // An omega.7, a Falcon, a Touch with its ttyACM, and a keyboard.
        for (dir, vid, pid, product, dev) in [
            ("1-1", "1451", "0301", "omega.7", 5),
            ("1-2", "0403", "cb48", "FALCON HAPTIC", 6),
            ("1-3", "2988", "0302", "Touch", 7),
            ("1-4", "046d", "c31c", "Keyboard", 8),
        ] {
            let d = sys.join(dir);
            write(&d.join("idVendor"), &format!("{vid}\n"));
            write(&d.join("idProduct"), &format!("{pid}\n"));
            write(&d.join("product"), &format!("{product}\n"));
            write(&d.join("busnum"), "1\n");
            write(&d.join("devnum"), &format!("{dev}\n"));
        }
        write(&sys.join("1-3/1-3:1.0/tty/ttyACM0/dev"), "166:0\n");
        let dev = root.path().join("dev");
        write(&dev.join("bus/usb/001/005"), "");
        let found = usb_devices(root.path(), &dev);
        let ids: Vec<&str> = found.iter().map(|d| d.id.as_str()).collect();
        assert_eq!(ids, ["1451:0301", "0403:cb48", "2988:0302"]);
        assert!(found[0].backend.contains("--device dhd"));
        assert_eq!(found[0].access[0].node, dev.join("bus/usb/001/005"));
        assert_eq!(found[2].access[0].node, dev.join("ttyACM0"));
        // The Falcon's node does not exist: said so.
        assert!(
            found[1].access[0].detail.contains("does not exist"),
            "{:?}",
            found[1]
        );
        assert!(!found[1].access[0].ok);
    }

    #[test]
    fn refusals_name_the_rules() {
        let rule = usb_rule(0x1451, None);
        assert_eq!(
            rule,
            r#"SUBSYSTEM=="usb", ATTRS{idVendor}=="1451", GROUP="haptics", MODE="0660", TAG+="uaccess""#
        );
        assert!(usb_rule(0x0403, Some(0xcb48)).contains(r#"ATTRS{idProduct}=="cb48""#));
        assert_eq!(mode_string(0o660), "rw-rw----");
        assert_eq!(known(0x046d, 0xc626).map(|k| k.backend), Some("hid"));
        assert_eq!(
            known(0x046d, 0xc31c),
            None,
            "a Logitech keyboard is not a SpaceMouse"
        );
        assert_eq!(known(0x0403, 0x6001), None, "an FTDI cable is not a Falcon");
    }
}
