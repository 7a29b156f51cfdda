//! `replay`: plays a recording made with `--record` (positions, buttons, timing).
//!
//! The recording's time base is shifted so its first tick lands on the first `read`; each read
//! returns the last recorded tick at or before `now` (so playback keeps the recorded timing at
//! any servo rate). At the end it holds the last sample, or loops when asked. Forces written
//! are accepted and ignored (a recording cannot react). No allocation after `open`.

use std::path::Path;

use glam::Vec3;

use super::{Device, DeviceError, DeviceInfo, DeviceSample};
use crate::telemetry::record::{self, RecordedTick};

/// The replay device; see the module doc.
#[derive(Debug)]
pub struct ReplayDevice {
    info: DeviceInfo,
    ticks: Vec<RecordedTick>,
    start_ns: Option<u64>,
    index: usize,
    looped: bool,
    last_force: Vec3,
}

impl ReplayDevice {
    /// Load `path`; `looped` restarts at the end.
    pub fn open(path: &Path, looped: bool) -> Result<Self, DeviceError> {
        Ok(Self::from_ticks(
            record::load(path)?,
            looped,
            path.display().to_string(),
        ))
    }

    /// Play `ticks` (non-empty, time-ordered).
    pub fn from_ticks(ticks: Vec<RecordedTick>, looped: bool, name: String) -> Self {
        let mut info = DeviceInfo::phantom_class(&format!("replay of {name}"));
        info.dof_output = 0;
        Self {
            info,
            ticks,
            start_ns: None,
            index: 0,
            looped,
            last_force: Vec3::ZERO,
        }
    }

    /// The last force written (for tests).
    pub fn last_force(&self) -> Vec3 {
        self.last_force
    }
}

impl Device for ReplayDevice {
    fn info(&self) -> &DeviceInfo {
        &self.info
    }

    fn read(&mut self, now_ns: u64) -> Result<DeviceSample, DeviceError> {
        let (Some(first), Some(last)) = (self.ticks.first(), self.ticks.last()) else {
            return Err(DeviceError::Io("empty recording".into()));
        };
        let (t_first, t_last) = (first.t_ns, last.t_ns);
        let start = *self.start_ns.get_or_insert(now_ns);
        let mut t = t_first + now_ns.saturating_sub(start);
        if t > t_last && self.looped {
            let span = (t_last - t_first).max(1);
            t = t_first + (t - t_first) % span;
            if self.ticks[self.index].t_ns > t {
                self.index = 0;
            }
        }
        while self.index + 1 < self.ticks.len() && self.ticks[self.index + 1].t_ns <= t {
            self.index += 1;
        }
        Ok(self.ticks[self.index].sample)
    }

    fn write_force(&mut self, force: Vec3) -> Result<(), DeviceError> {
        self.last_force = force;
        Ok(())
    }
}
