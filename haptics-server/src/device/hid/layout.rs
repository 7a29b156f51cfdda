//! Report layouts of HID force devices, from a TOML file:
//!
//! ```toml
//! name = "Bench rig v2"
//! max_force_n = 2.0
//! max_stiffness_n_per_m = 500.0
//! [input]
//! report_id = 1                      # first byte of the input report (omit: no id byte)
//! x = { offset = 1, size = 2, signed = true, scale = 1e-5 }   # m per count
//! y = { offset = 3, size = 2, signed = true, scale = 1e-5 }
//! z = { offset = 5, size = 2, signed = true, scale = 1e-5 }
//! buttons = { offset = 7, size = 1 }
//! [force]
//! report_id = 2
//! length = 7                         # bytes of the output report, id included
//! x = { offset = 1, size = 2, signed = true, scale = 1e-3 }   # N per count
//! y = { offset = 3, size = 2, signed = true, scale = 1e-3 }
//! z = { offset = 5, size = 2, signed = true, scale = 1e-3 }
//! ```
//!
//! Fields are little-endian integers of 1, 2 or 4 bytes. Loading checks every field fits its
//! report; decoding ignores reports with another id or too short; encoding rounds and
//! saturates to the field's integer range. No allocation per report.

use std::path::Path;

use glam::Vec3;
use serde::Deserialize;

use crate::device::{DeviceError, DeviceSample};

/// One integer field of a report.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Field {
    /// Byte offset in the report (the report id, if any, is byte 0).
    pub offset: usize,
    /// 1, 2 or 4 bytes.
    pub size: usize,
    /// Two's complement.
    #[serde(default)]
    pub signed: bool,
    /// Physical units per count.
    #[serde(default = "one")]
    pub scale: f32,
}

fn one() -> f32 {
    1.0
}

/// The input report.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InputLayout {
    /// Report id byte, if the device numbers its reports.
    pub report_id: Option<u8>,
    /// Encoder fields, m per count.
    pub x: Field,
    /// See `x`.
    pub y: Field,
    /// See `x`.
    pub z: Field,
    /// Button bits.
    pub buttons: Option<Field>,
}

/// The force output report.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ForceLayout {
    /// Report id byte (0 when the device uses none, as hidapi expects).
    #[serde(default)]
    pub report_id: u8,
    /// Report length in bytes, id included (≤ 64).
    pub length: usize,
    /// Force fields, N per count.
    pub x: Field,
    /// See `x`.
    pub y: Field,
    /// See `x`.
    pub z: Field,
}

/// A whole layout file.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Layout {
    /// Device name.
    pub name: String,
    /// Force limit, N.
    #[serde(default)]
    pub max_force_n: f32,
    /// Stiffness limit, N/m.
    #[serde(default = "default_stiffness")]
    pub max_stiffness_n_per_m: f32,
    /// Input report.
    pub input: InputLayout,
    /// Output report (omit for input-only devices).
    pub force: Option<ForceLayout>,
}

fn default_stiffness() -> f32 {
    500.0
}

impl Layout {
    /// Parse and check a layout.
    pub fn from_toml(text: &str, file: &str) -> Result<Self, DeviceError> {
        let bad = |reason: String| DeviceError::Parse {
            file: file.into(),
            line: 0,
            reason,
        };
        let l: Layout = toml::from_str(text).map_err(|e| bad(e.to_string()))?;
        let mut fields: Vec<(&str, Field, usize)> = vec![
            ("input.x", l.input.x, 64),
            ("input.y", l.input.y, 64),
            ("input.z", l.input.z, 64),
        ];
        if let Some(b) = l.input.buttons {
            fields.push(("input.buttons", b, 64));
        }
        if let Some(f) = &l.force {
            if f.length == 0 || f.length > 64 {
                return Err(bad("force.length must be 1 … 64".into()));
            }
            fields.extend([
                ("force.x", f.x, f.length),
                ("force.y", f.y, f.length),
                ("force.z", f.z, f.length),
            ]);
        }
        for (name, f, len) in fields {
            if ![1, 2, 4].contains(&f.size) {
                return Err(bad(format!("{name}.size must be 1, 2 or 4")));
            }
            if f.offset + f.size > len {
                return Err(bad(format!(
                    "{name} (offset {} size {}) does not fit a {len}-byte report",
                    f.offset, f.size
                )));
            }
            if !(f.scale.is_finite() && f.scale != 0.0) {
                return Err(bad(format!("{name}.scale must be finite and non-zero")));
            }
        }
        if !(l.max_force_n.is_finite() && l.max_force_n >= 0.0) {
            return Err(bad("max_force_n must be finite and >= 0".into()));
        }
        Ok(l)
    }

    /// Load a layout file.
    pub fn load(path: &Path) -> Result<Self, DeviceError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| DeviceError::Parse {
            file: file.clone(),
            line: 0,
            reason: e.to_string(),
        })?;
        Self::from_toml(&text, &file)
    }

    /// Update `sample` from one input report (ignored if not ours or too short).
    pub fn decode_input(&self, report: &[u8], sample: &mut DeviceSample) {
        let i = &self.input;
        if let Some(id) = i.report_id
            && report.first() != Some(&id)
        {
            return;
        }
        let (Some(x), Some(y), Some(z)) =
            (read(report, &i.x), read(report, &i.y), read(report, &i.z))
        else {
            return;
        };
        sample.position = Vec3::new(x, y, z);
        if let Some(b) = i.buttons.as_ref().and_then(|f| read_raw(report, f)) {
            sample.buttons = b as u16;
        }
    }

    /// Encode `force` into `out`; returns the report length (`None` for input-only layouts).
    pub fn encode_force(&self, force: Vec3, out: &mut [u8; 64]) -> Option<usize> {
        let f = self.force.as_ref()?;
        out[..f.length].fill(0);
        out[0] = f.report_id;
        let force = if force.is_finite() { force } else { Vec3::ZERO };
        for (field, v) in [(f.x, force.x), (f.y, force.y), (f.z, force.z)] {
            write(out, &field, v);
        }
        Some(f.length)
    }
}

fn read_raw(report: &[u8], f: &Field) -> Option<i64> {
    let bytes = report.get(f.offset..f.offset + f.size)?;
    let mut le = [0u8; 8];
    le[..f.size].copy_from_slice(bytes);
    let raw = u64::from_le_bytes(le);
    Some(if f.signed {
        let shift = 64 - 8 * f.size as u32;
        ((raw << shift) as i64) >> shift
    } else {
        raw as i64
    })
}

fn read(report: &[u8], f: &Field) -> Option<f32> {
    read_raw(report, f).map(|v| v as f32 * f.scale)
}

fn write(out: &mut [u8; 64], f: &Field, value: f32) {
    let bits = 8 * f.size as u32;
    let (lo, hi) = if f.signed {
        (-(1i64 << (bits - 1)), (1i64 << (bits - 1)) - 1)
    } else {
        (0, (1i64 << bits) - 1)
    };
    let counts = ((value / f.scale).round() as i64).clamp(lo, hi);
    out[f.offset..f.offset + f.size].copy_from_slice(&counts.to_le_bytes()[..f.size]);
}
