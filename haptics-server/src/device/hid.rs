//! `hid`: HID devices through hidapi (pure-Rust `linux-native-basic-udev` backend, no system
//! library), in two profiles behind the same [`Device`] trait:
//!
//! - **spacemouse**: a 6-DOF input device (3Dconnexion-class reports: id 1 translation
//!   `3×i16`, id 2 rotation `3×i16`, or id 1 with all six; id 3 buttons). The cap is a rate
//!   controller, so its deflection is integrated into a cursor position inside the workspace.
//!   No force output (`dof_output = 0`).
//! - **layout**: a HID force device described by a TOML report layout ([`layout`]): offsets,
//!   sizes, signedness and scales of the encoder and force fields.
//!
//! Report bytes come through [`ReportIo`]: the real `hidapi::HidDevice`, or [`RecordedReports`]
//! in tests, so both profiles are tested through exactly the code the hardware uses.

pub mod layout;

use glam::{Quat, Vec3};

use super::{Device, DeviceError, DeviceInfo, DeviceSample};
use layout::Layout;

/// Where report bytes come from and go to.
pub trait ReportIo: Send {
    /// The next input report if one is waiting (never blocks); `Ok(0)` when none.
    fn read_report(&mut self, buf: &mut [u8]) -> Result<usize, DeviceError>;
    /// Send an output report (first byte = report id, 0 if the device uses none).
    fn write_report(&mut self, report: &[u8]) -> Result<(), DeviceError>;
}

impl ReportIo for hidapi::HidDevice {
    fn read_report(&mut self, buf: &mut [u8]) -> Result<usize, DeviceError> {
        self.read_timeout(buf, 0)
            .map_err(|e| DeviceError::Io(e.to_string()))
    }
    fn write_report(&mut self, report: &[u8]) -> Result<(), DeviceError> {
        self.write(report)
            .map(|_| ())
            .map_err(|e| DeviceError::Io(e.to_string()))
    }
}

/// Recorded input reports played in order, one batch per read call; output reports kept.
#[derive(Debug, Default)]
pub struct RecordedReports {
    /// Input reports still to deliver.
    pub input: std::collections::VecDeque<Vec<u8>>,
    /// Output reports written.
    pub output: Vec<Vec<u8>>,
}

impl ReportIo for RecordedReports {
    fn read_report(&mut self, buf: &mut [u8]) -> Result<usize, DeviceError> {
        let Some(r) = self.input.pop_front() else {
            return Ok(0);
        };
        let n = r.len().min(buf.len());
        buf[..n].copy_from_slice(&r[..n]);
        Ok(n)
    }
    fn write_report(&mut self, report: &[u8]) -> Result<(), DeviceError> {
        self.output.push(report.to_vec());
        Ok(())
    }
}

/// Which interpretation of the reports.
#[derive(Debug, Clone, PartialEq)]
pub enum Profile {
    /// SpaceMouse-class 6-DOF input, integrated as rate control.
    SpaceMouse {
        /// Cursor speed at full deflection (±350 counts), m/s.
        speed_m_s: f32,
    },
    /// A report-layout force device.
    Layout(Box<Layout>),
}

/// A HID device with a profile; see the module doc.
#[derive(Debug)]
pub struct HidDevice<Io: ReportIo> {
    io: Io,
    profile: Profile,
    info: DeviceInfo,
    translation: Vec3,
    rotation: Vec3,
    sample: DeviceSample,
    last_ns: Option<u64>,
    buf: [u8; 64],
    out: [u8; 64],
}

/// Full-scale deflection of a SpaceMouse axis, counts.
pub const SPACEMOUSE_FULL_SCALE: f32 = 350.0;

impl<Io: ReportIo> HidDevice<Io> {
    /// Wrap `io` with `profile`.
    pub fn new(io: Io, profile: Profile, name: &str) -> Self {
        let mut info = DeviceInfo::phantom_class(name);
        match &profile {
            Profile::SpaceMouse { .. } => {
                info.dof_output = 0;
                info.max_force_n = 0.0;
            }
            Profile::Layout(l) => {
                info.dof_input = 3;
                info.dof_output = if l.force.is_some() { 3 } else { 0 };
                info.max_force_n = l.max_force_n;
                info.max_stiffness_n_per_m = l.max_stiffness_n_per_m;
            }
        }
        Self {
            io,
            profile,
            info,
            translation: Vec3::ZERO,
            rotation: Vec3::ZERO,
            sample: DeviceSample::default(),
            last_ns: None,
            buf: [0; 64],
            out: [0; 64],
        }
    }

    /// The report source (tests read back written output reports).
    pub fn io(&self) -> &Io {
        &self.io
    }

    fn apply_spacemouse(&mut self, n: usize) {
        let b = &self.buf[..n];
        let axis = |i: usize| -> f32 {
            b.get(1 + 2 * i..3 + 2 * i)
                .map_or(0.0, |s| f32::from(i16::from_le_bytes([s[0], s[1]])))
        };
        match b.first() {
            Some(1) if n >= 13 => {
                self.translation = Vec3::new(axis(0), axis(1), axis(2));
                self.rotation = Vec3::new(axis(3), axis(4), axis(5));
            }
            Some(1) if n >= 7 => self.translation = Vec3::new(axis(0), axis(1), axis(2)),
            Some(2) if n >= 7 => self.rotation = Vec3::new(axis(0), axis(1), axis(2)),
            Some(3) if n >= 2 => {
                self.sample.buttons = u16::from_le_bytes([b[1], b.get(2).copied().unwrap_or(0)]);
            }
            _ => {}
        }
    }
}

impl<Io: ReportIo> Device for HidDevice<Io> {
    fn info(&self) -> &DeviceInfo {
        &self.info
    }

    fn read(&mut self, now_ns: u64) -> Result<DeviceSample, DeviceError> {
        let dt = self
            .last_ns
            .map_or(0.0, |t| now_ns.saturating_sub(t) as f32 * 1e-9)
            .min(0.05);
        self.last_ns = Some(now_ns);
        let before = self.sample.position;
        for _ in 0..16 {
            let n = self.io.read_report(&mut self.buf)?;
            if n == 0 {
                break;
            }
            match &self.profile {
                Profile::SpaceMouse { .. } => self.apply_spacemouse(n),
                Profile::Layout(l) => l.decode_input(&self.buf[..n], &mut self.sample),
            }
        }
        if let Profile::SpaceMouse { speed_m_s } = self.profile {
            let v = self.translation / SPACEMOUSE_FULL_SCALE * speed_m_s;
            let p = (self.sample.position + v * dt)
                .clamp(self.info.workspace_min, self.info.workspace_max);
            let w = self.rotation / SPACEMOUSE_FULL_SCALE * std::f32::consts::PI;
            let q = Quat::from_scaled_axis(w * dt) * self.sample.orientation;
            self.sample.position = p;
            self.sample.orientation = q.normalize();
        }
        if dt > 0.0 {
            self.sample.velocity = (self.sample.position - before) / dt;
        }
        Ok(self.sample)
    }

    fn write_force(&mut self, force: Vec3) -> Result<(), DeviceError> {
        let Profile::Layout(l) = &self.profile else {
            return Ok(());
        };
        match l.encode_force(force, &mut self.out) {
            Some(n) => self.io.write_report(&self.out[..n]),
            None => Ok(()),
        }
    }

    fn stop(&mut self) {
        let _ = self.write_force(Vec3::ZERO);
    }
}

/// One line per attached HID device: `vid:pid  product (manufacturer)  path`.
pub fn list() -> Result<Vec<String>, DeviceError> {
    let api = hidapi::HidApi::new().map_err(|e| DeviceError::Open(e.to_string()))?;
    Ok(api
        .device_list()
        .map(|d| {
            format!(
                "{:04x}:{:04x}  {} ({})  {}",
                d.vendor_id(),
                d.product_id(),
                d.product_string().unwrap_or("?"),
                d.manufacturer_string().unwrap_or("?"),
                d.path().to_string_lossy()
            )
        })
        .collect())
}

/// 3Dconnexion's USB vendor ids (old Logitech-era and current).
pub const SPACEMOUSE_VENDORS: [u16; 2] = [0x046d, 0x256f];

/// Open the first device matching `vendor`/`product` (SpaceMouse vendors when `None`).
pub fn open(
    vendor: Option<u16>,
    product: Option<u16>,
    profile: Profile,
) -> Result<HidDevice<hidapi::HidDevice>, DeviceError> {
    let api = hidapi::HidApi::new().map_err(|e| DeviceError::Open(e.to_string()))?;
    let found = api.device_list().find(|d| {
        vendor.map_or(SPACEMOUSE_VENDORS.contains(&d.vendor_id()), |v| {
            v == d.vendor_id()
        }) && product.is_none_or(|p| p == d.product_id())
    });
    let Some(d) = found else {
        let wanted = match (vendor, product) {
            (None, _) => "no 3Dconnexion (SpaceMouse) HID device is attached".to_owned(),
            (Some(v), None) => format!("no HID device with vendor id {v:04x} is attached"),
            (Some(v), Some(p)) => format!("no HID device {v:04x}:{p:04x} is attached"),
        };
        return Err(DeviceError::Open(format!(
            "{wanted}; `haptics-server devices` lists what is attached"
        )));
    };
    let name = d.product_string().unwrap_or("HID device").to_owned();
    let dev = d.open_device(&api).map_err(|e| {
        DeviceError::Open(format!(
            "{name}: {e} (check udev permissions on /dev/hidraw*)"
        ))
    })?;
    Ok(HidDevice::new(dev, profile, &name))
}

#[cfg(test)]
mod tests;
