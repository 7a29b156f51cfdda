//! `dhd`: Force Dimension devices (omega.x, delta.x, sigma.x, and the Novint Falcon through
//! their SDK) through the vendor's DHD library (`libdhd.so`), loaded at run time with
//! `libloading`: no build-time dependency, and without the library the backend says which
//! file names it looked for and where ([`super::library`]).
//!
//! Unlike OpenHaptics, DHD has no scheduler of its own: the servo driver thread times the loop
//! and calls [`Device::read`] (`dhdGetPosition`, `dhdGetOrientationFrame` on devices with a
//! wrist, `dhdGetLinearVelocity`, `dhdGetButtonMask`) and [`Device::write_force`]
//! (`dhdSetForce`) once per tick. Units are SI already (m, m/s, N). The device frame is the
//! vendor's: origin at the workspace centre, x toward the user, y to the right, z up.
//! Limits per model (force, stiffness, workspace radius) follow CHAI3D's device table
//! ([`model`]); the server's own `safety` limits still apply and the lower wins.
//!
//! Signatures are those of `dhdc.h` (SDK 3.x): every call takes the device id as a trailing
//! `char` (`-1`: the default device); most return `int`, `< 0` on error with the reason from
//! `dhdErrorGetLastStr()`, and `DHD_TIMEGUARD` (1) / `DHD_MOTOR_SATURATED` (2) are not errors.
//! Tested against a stand-in library the test suite builds from C
//! (`tests/stand-ins/dhd_standin.c`).

use std::ffi::{CStr, c_char, c_int, c_uchar, c_uint, c_ushort, c_void};

use glam::{DMat3, DQuat, DVec3, Quat, Vec3};

use super::library;
use super::{Device, DeviceError, DeviceInfo, DeviceSample};

const DHD_ON: c_uchar = 1;
const DHD_OFF: c_uchar = 0;

/// The DHD functions the backend cannot do without (the list `probe` checks).
pub const REQUIRED: [&str; 8] = [
    "dhdOpen",
    "dhdClose",
    "dhdGetSystemType",
    "dhdEnableForce",
    "dhdGetPosition",
    "dhdSetForce",
    "dhdGetButtonMask",
    "dhdErrorGetLastStr",
];

/// Functions used when the library has them (older SDKs lack some): opening by index,
/// counting devices, the model's name, orientation, velocity, the SDK version.
pub const OPTIONAL: [&str; 6] = [
    "dhdOpenID",
    "dhdGetDeviceCount",
    "dhdGetSystemName",
    "dhdGetOrientationFrame",
    "dhdGetLinearVelocity",
    "dhdGetSDKVersion",
];

/// How `device.dhd.library` is installed, for error messages.
pub const INSTALL_HINT: &str = "install the Force Dimension SDK (forcedimension.com; it also \
    drives the Novint Falcon) and copy its lib/release/lin-*/libdhd.so.* to /usr/local/lib \
    (then `sudo ldconfig`)";

type Id = c_char;

#[derive(Debug, Clone, Copy)]
struct Api {
    open: unsafe extern "C" fn() -> c_int,
    open_id: Option<unsafe extern "C" fn(Id) -> c_int>,
    close: unsafe extern "C" fn(Id) -> c_int,
    system_type: unsafe extern "C" fn(Id) -> c_int,
    enable_force: unsafe extern "C" fn(c_uchar, Id) -> c_int,
    get_position: unsafe extern "C" fn(*mut f64, *mut f64, *mut f64, Id) -> c_int,
    set_force: unsafe extern "C" fn(f64, f64, f64, Id) -> c_int,
    button_mask: unsafe extern "C" fn(Id) -> c_uint,
    last_error: unsafe extern "C" fn() -> *const c_char,
    device_count: Option<unsafe extern "C" fn() -> c_int>,
    system_name: Option<unsafe extern "C" fn(Id) -> *const c_char>,
    orientation_frame: Option<unsafe extern "C" fn(*mut [[f64; 3]; 3], Id) -> c_int>,
    linear_velocity: Option<unsafe extern "C" fn(*mut f64, *mut f64, *mut f64, Id) -> c_int>,
    sdk_version: Option<unsafe extern "C" fn(*mut c_int, *mut c_int, *mut c_int, *mut c_int)>,
}

impl Api {
    fn last_error(&self) -> String {
        // SAFETY: plain C call; the result is null or a NUL-terminated static string.
        let p = unsafe { (self.last_error)() };
        if p.is_null() {
            return "no error text".into();
        }
        // SAFETY: non-null, NUL-terminated, owned by the library.
        unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned()
    }
}

/// The library, loaded and checked.
#[derive(Debug)]
pub struct Library {
    api: Api,
    lib: libloading::Library,
    /// The requested name or path.
    pub requested: String,
}

/// Load `library` (a name the loader searches, or a path) and check it exports [`REQUIRED`].
/// Errors name the file names looked for and where, or the missing functions.
pub fn load(library: &str) -> Result<Library, DeviceError> {
    let lib = library::open(
        library,
        &REQUIRED,
        &library::Vendor {
            what: "the Force Dimension DHD library",
            config_key: "device.dhd.library",
            flag: "--dhd-library",
            install_hint: INSTALL_HINT,
            missing_hint: " (an SDK older than 3.2?)",
        },
    )?;
    macro_rules! sym {
        ($name:literal) => {
            // SAFETY: every required name was found above; the types match dhdc.h.
            *unsafe { lib.get($name.as_bytes()) }
                .map_err(|e| DeviceError::Missing(format!("{}: {e}", $name)))?
        };
    }
    macro_rules! opt {
        ($name:literal) => {
            // SAFETY: the types match dhdc.h; absent symbols give None.
            unsafe { lib.get($name.as_bytes()) }.ok().map(|s| *s)
        };
    }
    let api = Api {
        open: sym!("dhdOpen"),
        open_id: opt!("dhdOpenID"),
        close: sym!("dhdClose"),
        system_type: sym!("dhdGetSystemType"),
        enable_force: sym!("dhdEnableForce"),
        get_position: sym!("dhdGetPosition"),
        set_force: sym!("dhdSetForce"),
        button_mask: sym!("dhdGetButtonMask"),
        last_error: sym!("dhdErrorGetLastStr"),
        device_count: opt!("dhdGetDeviceCount"),
        system_name: opt!("dhdGetSystemName"),
        orientation_frame: opt!("dhdGetOrientationFrame"),
        linear_velocity: opt!("dhdGetLinearVelocity"),
        sdk_version: opt!("dhdGetSDKVersion"),
    };
    Ok(Library {
        api,
        lib,
        requested: library.into(),
    })
}

impl Library {
    /// The file the library was loaded from.
    pub fn path(&self) -> Option<std::path::PathBuf> {
        library::loaded_path(&self.lib, "dhdOpen")
    }

    /// Optional functions the library lacks (see [`OPTIONAL`]).
    pub fn missing_optional(&self) -> Vec<&'static str> {
        OPTIONAL
            .iter()
            // SAFETY: only the symbol's presence is checked.
            .filter(|n| unsafe { self.lib.get::<*const c_void>(n.as_bytes()) }.is_err())
            .copied()
            .collect()
    }

    /// `dhdGetDeviceCount()`: Force Dimension devices attached (`None` when the library
    /// cannot count).
    pub fn device_count(&self) -> Option<i32> {
        // SAFETY: plain C call without arguments.
        self.api.device_count.map(|f| unsafe { f() })
    }

    /// `dhdGetSDKVersion`, as `major.minor.release-revision`.
    pub fn sdk_version(&self) -> Option<String> {
        let f = self.api.sdk_version?;
        let (mut a, mut b, mut c, mut d) = (0, 0, 0, 0);
        // SAFETY: writes four ints into live locals.
        unsafe { f(&mut a, &mut b, &mut c, &mut d) };
        Some(format!("{a}.{b}.{c}-{d}"))
    }
}

/// Check `library` loads and exports every required function.
pub fn probe(library: &str) -> Result<Library, DeviceError> {
    load(library)
}

/// What a Force Dimension model can do (CHAI3D's device table; DESIGN §6).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Model {
    /// Model name.
    pub name: &'static str,
    /// Largest continuous force, N.
    pub max_force_n: f32,
    /// Largest stiffness rendered stably, N/m.
    pub max_stiffness_n_per_m: f32,
    /// Workspace radius around the origin, m.
    pub workspace_radius_m: f32,
    /// Has a wrist: orientation is sensed.
    pub wrist: bool,
}

/// The model behind a `dhdGetSystemType` value (`DHD_DEVICE_*` in dhdc.h). Unknown types get
/// the omega.3's figures, the smallest of the family but the Falcon.
pub fn model(system_type: i32) -> Model {
    let m = |name, max_force_n, max_stiffness_n_per_m, workspace_radius_m, wrist| Model {
        name,
        max_force_n,
        max_stiffness_n_per_m,
        workspace_radius_m,
        wrist,
    };
    match system_type {
        31 | 63 => m("delta.3", 20.0, 5000.0, 0.15, false),
        61 | 62 | 64 => m("delta.6", 20.0, 5000.0, 0.15, true),
        32 | 33 => m("omega.3", 12.0, 5000.0, 0.075, false),
        34 | 36 => m("omega.6", 12.0, 5000.0, 0.075, true),
        35 | 37 => m("omega.7", 12.0, 5000.0, 0.075, true),
        104 | 105 => m("sigma.7", 12.0, 4000.0, 0.09, true),
        106 | 107 => m("sigma.6+", 12.0, 4000.0, 0.09, true),
        60 => m("Novint Falcon", 8.0, 3000.0, 0.04, false),
        _ => m("Force Dimension device", 12.0, 5000.0, 0.075, false),
    }
}

/// A device driven through the DHD library; see the module doc.
#[derive(Debug)]
pub struct DhdDevice {
    info: DeviceInfo,
    api: Api,
    id: Id,
    model: Model,
    system_type: i32,
    last: Option<(u64, Vec3)>,
    _lib: libloading::Library,
}

impl DhdDevice {
    /// Load `library` and open the device number `index` (`None`: the first one, `dhdOpen`).
    pub fn open(library: &str, index: Option<u8>) -> Result<Self, DeviceError> {
        let Library { api, lib, .. } = load(library)?;
        let id = match index {
            None => {
                // SAFETY: plain C call.
                unsafe { (api.open)() }
            }
            Some(i) => {
                let open_id = api.open_id.ok_or_else(|| {
                    DeviceError::Missing(format!(
                        "{library:?} lacks dhdOpenID, needed for device.dhd.index"
                    ))
                })?;
                // SAFETY: plain C call with a small index.
                unsafe { open_id(i as Id) }
            }
        };
        if id < 0 {
            // SAFETY: plain C call.
            let count = api.device_count.map(|f| unsafe { f() });
            let attached = match count {
                Some(0) => "no Force Dimension device is attached or powered".to_owned(),
                Some(n) => format!("{n} attached"),
                None => "the library cannot count devices".into(),
            };
            return Err(DeviceError::Open(format!(
                "dhdOpen{} failed: {} ({attached}); `haptics-server devices` lists USB \
                 devices and their permissions",
                index.map_or(String::new(), |i| format!("ID({i})")),
                api.last_error()
            )));
        }
        let id = id as Id;
        // SAFETY: `id` is an open device.
        let system_type = unsafe { (api.system_type)(id) };
        let model = model(system_type);
        let reported = api.system_name.and_then(|f| {
            // SAFETY: `id` is open; the result is null or a static NUL-terminated string.
            let p = unsafe { f(id) };
            if p.is_null() {
                return None;
            }
            // SAFETY: non-null, NUL-terminated, owned by the library.
            Some(unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned())
        });
        let r = model.workspace_radius_m;
        let info = DeviceInfo {
            name: format!(
                "Force Dimension {} (DHD type {system_type})",
                reported.as_deref().unwrap_or(model.name)
            ),
            dof_input: if model.wrist { 6 } else { 3 },
            dof_output: 3,
            workspace_min: Vec3::splat(-r),
            workspace_max: Vec3::splat(r),
            max_force_n: model.max_force_n,
            max_stiffness_n_per_m: model.max_stiffness_n_per_m,
        };
        Ok(Self {
            info,
            api,
            id,
            model,
            system_type,
            last: None,
            _lib: lib,
        })
    }

    /// The model's figures.
    pub fn model(&self) -> Model {
        self.model
    }

    /// `dhdGetSystemType`.
    pub fn system_type(&self) -> i32 {
        self.system_type
    }

    fn orientation(&self) -> Quat {
        let Some(f) = self.api.orientation_frame.filter(|_| self.model.wrist) else {
            return Quat::IDENTITY;
        };
        let mut m = [[0f64; 3]; 3];
        // SAFETY: writes 9 doubles into a live local.
        if unsafe { f(&mut m, self.id) } < 0 {
            return Quat::IDENTITY;
        }
        // dhdc.h: matrix[row][col]; glam takes columns.
        let rot = DMat3::from_cols_array_2d(&m).transpose();
        DQuat::from_mat3(&rot).as_quat()
    }
}

impl Device for DhdDevice {
    fn info(&self) -> &DeviceInfo {
        &self.info
    }

    fn read(&mut self, now_ns: u64) -> Result<DeviceSample, DeviceError> {
        let (mut x, mut y, mut z) = (0f64, 0f64, 0f64);
        // SAFETY: writes 3 doubles into live locals.
        if unsafe { (self.api.get_position)(&mut x, &mut y, &mut z, self.id) } < 0 {
            return Err(DeviceError::Io(format!(
                "dhdGetPosition: {}",
                self.api.last_error()
            )));
        }
        let position = DVec3::new(x, y, z).as_vec3();
        let mut velocity = None;
        if let Some(f) = self.api.linear_velocity {
            let (mut vx, mut vy, mut vz) = (0f64, 0f64, 0f64);
            // SAFETY: writes 3 doubles into live locals.
            if unsafe { f(&mut vx, &mut vy, &mut vz, self.id) } >= 0 {
                velocity = Some(DVec3::new(vx, vy, vz).as_vec3());
            }
        }
        let velocity = velocity.unwrap_or_else(|| match self.last {
            Some((t, p)) if now_ns > t => (position - p) / ((now_ns - t) as f32 * 1e-9),
            _ => Vec3::ZERO,
        });
        self.last = Some((now_ns, position));
        // SAFETY: plain C call.
        let buttons = unsafe { (self.api.button_mask)(self.id) } as c_ushort;
        Ok(DeviceSample {
            position,
            orientation: self.orientation(),
            velocity,
            buttons,
        })
    }

    fn write_force(&mut self, force: Vec3) -> Result<(), DeviceError> {
        let f = if force.is_finite() {
            force.as_dvec3()
        } else {
            DVec3::ZERO
        };
        // SAFETY: plain C call.
        if unsafe { (self.api.set_force)(f.x, f.y, f.z, self.id) } < 0 {
            return Err(DeviceError::Io(format!(
                "dhdSetForce: {}",
                self.api.last_error()
            )));
        }
        Ok(())
    }

    fn start(&mut self) -> Result<(), DeviceError> {
        // SAFETY: plain C calls on the open device.
        let ok = unsafe {
            (self.api.set_force)(0.0, 0.0, 0.0, self.id);
            (self.api.enable_force)(DHD_ON, self.id)
        };
        if ok < 0 {
            return Err(DeviceError::Io(format!(
                "dhdEnableForce(DHD_ON): {}",
                self.api.last_error()
            )));
        }
        Ok(())
    }

    fn stop(&mut self) {
        let _ = self.write_force(Vec3::ZERO);
        // SAFETY: plain C call; force off also engages the brakes on devices that have them.
        unsafe { (self.api.enable_force)(DHD_OFF, self.id) };
    }
}

impl Drop for DhdDevice {
    fn drop(&mut self) {
        // SAFETY: `id` is ours and still open.
        unsafe { (self.api.close)(self.id) };
    }
}
