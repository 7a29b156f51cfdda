//! `openhaptics`: placeholder until the loader lands.

use glam::Vec3;

use super::{Device, DeviceError, DeviceInfo, DeviceSample};

/// Check `library` loads and exports what the backend needs.
pub fn probe(library: &str) -> Result<(), DeviceError> {
    Err(DeviceError::Missing(format!(
        "{library}: not implemented yet"
    )))
}

/// A device driven through the OpenHaptics HD library.
#[derive(Debug)]
pub struct OpenHapticsDevice {
    info: DeviceInfo,
}

impl OpenHapticsDevice {
    /// Load `library` and open `device_name`.
    pub fn open(library: &str, _device_name: &str) -> Result<Self, DeviceError> {
        Err(DeviceError::Missing(format!(
            "{library}: not implemented yet"
        )))
    }
}

impl Device for OpenHapticsDevice {
    fn info(&self) -> &DeviceInfo {
        &self.info
    }
    fn read(&mut self, _now_ns: u64) -> Result<DeviceSample, DeviceError> {
        Ok(DeviceSample::default())
    }
    fn write_force(&mut self, _force: Vec3) -> Result<(), DeviceError> {
        Ok(())
    }
}
