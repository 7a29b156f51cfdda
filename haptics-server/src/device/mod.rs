//! Devices behind one trait: read the stylus state, write a force.
//!
//! Contract for implementors: [`Device::read`] and [`Device::write_force`] are called once per
//! servo tick on the servo thread, so they must not allocate or block beyond the device's own
//! I/O. Units are SI in the device frame (m, m/s, N). Backends: [`fake`] (simulated hand and
//! stylus, closed loop), [`replay`] (a recorded session), [`hid`] (hidapi: SpaceMouse-class
//! input, report-layout force devices), [`openhaptics`] (the vendor HD library, loaded at run
//! time), [`dhd`] (Force Dimension's DHD library, loaded at run time). [`library`] finds and
//! explains vendor libraries; [`axes`] describes swapped and inverted axes.

pub mod axes;
pub mod dhd;
pub mod fake;
pub mod hid;
pub mod library;
pub mod openhaptics;
pub mod replay;

use glam::{Quat, Vec3};

/// What a device is and what it can do; sent to the workstation in `Welcome`.
#[derive(Debug, Clone, PartialEq)]
pub struct DeviceInfo {
    /// Model name for logs and `Welcome`.
    pub name: String,
    /// Degrees of freedom sensed (3 or 6).
    pub dof_input: u8,
    /// Degrees of freedom actuated (0 = input only, 3 = force).
    pub dof_output: u8,
    /// Workspace box, m.
    pub workspace_min: Vec3,
    /// Workspace box, m.
    pub workspace_max: Vec3,
    /// Largest force the device can output, N.
    pub max_force_n: f32,
    /// Largest stiffness the device renders stably, N/m.
    pub max_stiffness_n_per_m: f32,
}

impl DeviceInfo {
    /// A Phantom Omni / Touch class device (CHAI3D's table: 3.3 N, ~700 N/m, 0.1 m).
    pub fn phantom_class(name: &str) -> Self {
        Self {
            name: name.to_owned(),
            dof_input: 6,
            dof_output: 3,
            workspace_min: Vec3::splat(-0.08),
            workspace_max: Vec3::splat(0.08),
            max_force_n: 3.3,
            max_stiffness_n_per_m: 700.0,
        }
    }
}

/// One reading of the device.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DeviceSample {
    /// Stylus tip position, m.
    pub position: Vec3,
    /// Stylus orientation.
    pub orientation: Quat,
    /// Tip velocity, m/s.
    pub velocity: Vec3,
    /// Button bit mask, bit 0 = primary.
    pub buttons: u16,
}

impl Default for DeviceSample {
    fn default() -> Self {
        Self {
            position: Vec3::ZERO,
            orientation: Quat::IDENTITY,
            velocity: Vec3::ZERO,
            buttons: 0,
        }
    }
}

/// Why a device operation failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum DeviceError {
    /// The device could not be opened.
    #[error("cannot open device: {0}")]
    Open(String),
    /// A read or write failed.
    #[error("device I/O failed: {0}")]
    Io(String),
    /// A file (recording, path, profile) is malformed.
    #[error("{file}:{line}: {reason}")]
    Parse {
        /// The file.
        file: String,
        /// 1-based line (0 = whole file).
        line: usize,
        /// What is wrong.
        reason: String,
    },
    /// A vendor library or one of its functions is missing.
    #[error("{0}")]
    Missing(String),
}

/// A haptic (or input-only) device driven by the servo loop.
pub trait Device: Send {
    /// What the device is.
    fn info(&self) -> &DeviceInfo;
    /// The state now (`now_ns` on the server's monotonic clock). Called once per tick.
    fn read(&mut self, now_ns: u64) -> Result<DeviceSample, DeviceError>;
    /// Output `force` (N), already made safe by the servo loop. Called once per tick.
    fn write_force(&mut self, force: Vec3) -> Result<(), DeviceError>;
    /// Called on the servo thread before the first tick.
    fn start(&mut self) -> Result<(), DeviceError> {
        Ok(())
    }
    /// Called on the servo thread after the last tick; should leave the output at zero.
    fn stop(&mut self) {}
    /// A device whose vendor library runs its own servo scheduler (OpenHaptics) drives the
    /// loop: it calls `tick` once per scheduler period from the scheduler's callback, inside
    /// the device frame, until `tick` returns `false`, then returns. `None` (the default): the
    /// driver thread times the loop itself.
    fn run_scheduled(
        &mut self,
        _tick: &mut dyn FnMut(&mut dyn Device) -> bool,
    ) -> Option<Result<(), DeviceError>> {
        None
    }
}

impl Device for Box<dyn Device> {
    fn info(&self) -> &DeviceInfo {
        (**self).info()
    }
    fn read(&mut self, now_ns: u64) -> Result<DeviceSample, DeviceError> {
        (**self).read(now_ns)
    }
    fn write_force(&mut self, force: Vec3) -> Result<(), DeviceError> {
        (**self).write_force(force)
    }
    fn start(&mut self) -> Result<(), DeviceError> {
        (**self).start()
    }
    fn stop(&mut self) {
        (**self).stop()
    }
    fn run_scheduled(
        &mut self,
        tick: &mut dyn FnMut(&mut dyn Device) -> bool,
    ) -> Option<Result<(), DeviceError>> {
        (**self).run_scheduled(tick)
    }
}
