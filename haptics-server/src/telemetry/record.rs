//! Session recordings (`--record FILE`), played back by the `replay` device.
//!
//! Text, one tick per line, so a recording can be inspected and plotted with anything:
//!
//! ```text
//! # haptics-server recording v1
//! t_ns,px,py,pz,qx,qy,qz,qw,vx,vy,vz,buttons,fx,fy,fz,engaged
//! 1000000,0.01,0,0.05,0,0,0,1,0,0,0,0,0,0,0,0
//! ```
//!
//! `t_ns` is the server clock; positions m, velocities m/s, forces N (the force written).

use std::io::{BufWriter, Write};
use std::path::Path;

use glam::{Quat, Vec3};

use super::TickRecord;
use crate::device::{DeviceError, DeviceSample};

/// First line of every recording.
pub const MAGIC_LINE: &str = "# haptics-server recording v1";
/// Column header line.
pub const HEADER: &str = "t_ns,px,py,pz,qx,qy,qz,qw,vx,vy,vz,buttons,fx,fy,fz,engaged";

/// Writes a recording.
#[derive(Debug)]
pub struct Recorder {
    out: BufWriter<std::fs::File>,
}

impl Recorder {
    /// Create (truncate) `path` and write the header.
    pub fn create(path: &Path) -> std::io::Result<Self> {
        let mut out = BufWriter::new(std::fs::File::create(path)?);
        writeln!(out, "{MAGIC_LINE}\n{HEADER}")?;
        Ok(Self { out })
    }

    /// Append one tick.
    pub fn write(&mut self, r: &TickRecord) -> std::io::Result<()> {
        let c = &r.cursor;
        let (p, q, v, f) = (c.position, c.orientation, c.velocity, c.output_force);
        writeln!(
            self.out,
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
            r.now_ns,
            p.x,
            p.y,
            p.z,
            q.x,
            q.y,
            q.z,
            q.w,
            v.x,
            v.y,
            v.z,
            c.buttons,
            f.x,
            f.y,
            f.z,
            u8::from(c.engaged)
        )
    }

    /// Flush buffered lines to the file.
    pub fn flush(&mut self) -> std::io::Result<()> {
        self.out.flush()
    }
}

/// One recorded tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RecordedTick {
    /// Server clock at the tick, ns.
    pub t_ns: u64,
    /// The device reading.
    pub sample: DeviceSample,
    /// The force written, N.
    pub force: Vec3,
}

/// Read a whole recording; errors name the line.
pub fn load(path: &Path) -> Result<Vec<RecordedTick>, DeviceError> {
    let file = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|e| DeviceError::Parse {
        file: file.clone(),
        line: 0,
        reason: e.to_string(),
    })?;
    let mut lines = text.lines().enumerate();
    if lines.next().map(|(_, l)| l.trim()) != Some(MAGIC_LINE) {
        return Err(DeviceError::Parse {
            file,
            line: 1,
            reason: format!("not a recording: first line must be {MAGIC_LINE:?}"),
        });
    }
    let mut ticks = Vec::new();
    for (i, line) in lines {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') || line.starts_with("t_ns") {
            continue;
        }
        let bad = |reason: String| DeviceError::Parse {
            file: file.clone(),
            line: i + 1,
            reason,
        };
        let cols: Vec<&str> = line.split(',').collect();
        if cols.len() != 16 {
            return Err(bad(format!("expected 16 columns, got {}", cols.len())));
        }
        let t_ns = cols[0]
            .parse::<u64>()
            .map_err(|e| bad(format!("t_ns: {e}")))?;
        let buttons = cols[11]
            .parse::<u16>()
            .map_err(|e| bad(format!("buttons: {e}")))?;
        let mut f = [0f32; 16];
        for (j, c) in cols.iter().enumerate() {
            if j == 0 || j == 11 {
                continue;
            }
            f[j] = c
                .parse::<f32>()
                .map_err(|e| bad(format!("column {}: {e}", j + 1)))?;
            if !f[j].is_finite() {
                return Err(bad(format!("column {}: non-finite", j + 1)));
            }
        }
        if ticks.last().is_some_and(|t: &RecordedTick| t_ns < t.t_ns) {
            return Err(bad("time goes backwards".into()));
        }
        let orientation = Quat::from_xyzw(f[4], f[5], f[6], f[7]);
        ticks.push(RecordedTick {
            t_ns,
            sample: DeviceSample {
                position: Vec3::new(f[1], f[2], f[3]),
                orientation: if orientation.is_normalized() {
                    orientation
                } else {
                    Quat::IDENTITY
                },
                velocity: Vec3::new(f[8], f[9], f[10]),
                buttons,
            },
            force: Vec3::new(f[12], f[13], f[14]),
        });
    }
    if ticks.is_empty() {
        return Err(DeviceError::Parse {
            file,
            line: 0,
            reason: "recording has no ticks".into(),
        });
    }
    Ok(ticks)
}
