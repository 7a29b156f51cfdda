//! `openhaptics`: a Touch / Phantom through the vendor's HD library (`libHD.so`), loaded at run
//! time with `libloading`: no build-time dependency, and without the library the backend says
//! exactly what is missing (the file, or which functions it lacks).
//!
//! The HD scheduler drives the servo loop ([`Device::run_scheduled`]): one asynchronous
//! callback at the highest priority runs the whole servo tick between `hdBeginFrame` and
//! `hdEndFrame`, reading position/velocity/buttons and setting the force there, as the vendor
//! requires. Units are converted at this boundary (HD: mm, mm/s, N/mm; here: m, m/s, N/m).
//! Tested against a stand-in library the test suite builds from C
//! (`tests/stand-ins/hd_standin.c`), which exports the same functions and simulates a stylus.

use std::ffi::{CString, c_char, c_int, c_uint, c_ulong, c_ushort, c_void};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use glam::{DVec3, Vec3};

use super::{Device, DeviceError, DeviceInfo, DeviceSample};

const HD_INVALID_HANDLE: c_uint = 0xFFFF_FFFF;
const HD_SUCCESS: c_uint = 0;
const HD_CURRENT_BUTTONS: c_uint = 0x2000;
const HD_CURRENT_POSITION: c_uint = 0x2050;
const HD_CURRENT_VELOCITY: c_uint = 0x2051;
const HD_NOMINAL_MAX_STIFFNESS: c_uint = 0x2602;
const HD_NOMINAL_MAX_FORCE: c_uint = 0x2603;
const HD_CURRENT_FORCE: c_uint = 0x2700;
const HD_FORCE_OUTPUT: c_uint = 0x4000;
const HD_CALLBACK_DONE: c_uint = 0;
const HD_CALLBACK_CONTINUE: c_uint = 1;
const HD_MAX_SCHEDULER_PRIORITY: c_ushort = 0xffff;

/// `HDErrorInfo`.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
struct HdErrorInfo {
    error_code: c_uint,
    internal_error_code: c_int,
    device: c_uint,
}

type Callback = unsafe extern "C" fn(*mut c_void) -> c_uint;

/// The HD functions the backend uses, by name (the list `probe` checks).
pub const REQUIRED: [&str; 14] = [
    "hdInitDevice",
    "hdDisableDevice",
    "hdMakeCurrentDevice",
    "hdGetError",
    "hdEnable",
    "hdBeginFrame",
    "hdEndFrame",
    "hdGetDoublev",
    "hdGetIntegerv",
    "hdSetDoublev",
    "hdScheduleAsynchronous",
    "hdUnschedule",
    "hdStartScheduler",
    "hdStopScheduler",
];

#[derive(Debug, Clone, Copy)]
struct Api {
    init: unsafe extern "C" fn(*const c_char) -> c_uint,
    disable: unsafe extern "C" fn(c_uint),
    make_current: unsafe extern "C" fn(c_uint),
    get_error: unsafe extern "C" fn() -> HdErrorInfo,
    enable: unsafe extern "C" fn(c_uint),
    begin: unsafe extern "C" fn(c_uint),
    end: unsafe extern "C" fn(c_uint),
    get_doublev: unsafe extern "C" fn(c_uint, *mut f64),
    get_integerv: unsafe extern "C" fn(c_uint, *mut c_int),
    set_doublev: unsafe extern "C" fn(c_uint, *const f64),
    schedule: unsafe extern "C" fn(Callback, *mut c_void, c_ushort) -> c_ulong,
    unschedule: unsafe extern "C" fn(c_ulong),
    start: unsafe extern "C" fn(),
    stop: unsafe extern "C" fn(),
}

fn load(library: &str) -> Result<(libloading::Library, Api), DeviceError> {
    let lib = super::library::open(
        library,
        &REQUIRED,
        &super::library::Vendor {
            what: "the OpenHaptics HD library",
            config_key: "device.openhaptics.library",
            flag: "--openhaptics-library",
            install_hint: INSTALL_HINT,
            missing_hint: "",
        },
    )?;
    macro_rules! sym {
        ($name:literal) => {
            // SAFETY: every name was found above; the types match the HD headers
            // (hdDefines.h / hdDevice.h / hdScheduler.h).
            *unsafe { lib.get($name.as_bytes()) }
                .map_err(|e| DeviceError::Missing(format!("{}: {e}", $name)))?
        };
    }
    let api = Api {
        init: sym!("hdInitDevice"),
        disable: sym!("hdDisableDevice"),
        make_current: sym!("hdMakeCurrentDevice"),
        get_error: sym!("hdGetError"),
        enable: sym!("hdEnable"),
        begin: sym!("hdBeginFrame"),
        end: sym!("hdEndFrame"),
        get_doublev: sym!("hdGetDoublev"),
        get_integerv: sym!("hdGetIntegerv"),
        set_doublev: sym!("hdSetDoublev"),
        schedule: sym!("hdScheduleAsynchronous"),
        unschedule: sym!("hdUnschedule"),
        start: sym!("hdStartScheduler"),
        stop: sym!("hdStopScheduler"),
    };
    Ok((lib, api))
}

/// How `device.openhaptics.library` is installed, for error messages.
pub const INSTALL_HINT: &str = "install OpenHaptics and the Touch device driver from 3D Systems \
    (they put libHD.so in /usr/lib or /usr/lib64)";

/// Check `library` loads and exports every function the backend needs.
pub fn probe(library: &str) -> Result<(), DeviceError> {
    load(library).map(|_| ())
}

/// The file `library` loads from (`None` when it does not load).
pub fn loaded_path(library: &str) -> Option<std::path::PathBuf> {
    let (lib, _) = load(library).ok()?;
    super::library::loaded_path(&lib, "hdInitDevice")
}

/// A device driven through the HD library; see the module doc.
#[derive(Debug)]
pub struct OpenHapticsDevice {
    info: DeviceInfo,
    api: Api,
    handle: c_uint,
    _lib: libloading::Library,
}

impl OpenHapticsDevice {
    /// Load `library` and initialise `device_name` (empty: the default device).
    pub fn open(library: &str, device_name: &str) -> Result<Self, DeviceError> {
        let (lib, api) = load(library)?;
        let name = CString::new(device_name)
            .map_err(|_| DeviceError::Open("device name contains NUL".into()))?;
        let ptr = if device_name.is_empty() {
            std::ptr::null()
        } else {
            name.as_ptr()
        };
        // SAFETY: `ptr` is null (HD_DEFAULT_DEVICE) or a valid NUL-terminated string.
        let handle = unsafe { (api.init)(ptr) };
        // SAFETY: plain C call without arguments.
        let err = unsafe { (api.get_error)() };
        if handle == HD_INVALID_HANDLE || err.error_code != HD_SUCCESS {
            return Err(DeviceError::Open(format!(
                "hdInitDevice({device_name:?}) failed: HD error {:#06x} (internal {})",
                err.error_code, err.internal_error_code
            )));
        }
        let (mut max_force, mut max_k) = (0.0f64, 0.0f64);
        // SAFETY: `handle` is valid; each query writes one double into a live local.
        unsafe {
            (api.make_current)(handle);
            (api.get_doublev)(HD_NOMINAL_MAX_FORCE, &mut max_force);
            (api.get_doublev)(HD_NOMINAL_MAX_STIFFNESS, &mut max_k);
        }
        let mut info = DeviceInfo::phantom_class(&format!(
            "OpenHaptics {}",
            if device_name.is_empty() {
                "default device"
            } else {
                device_name
            }
        ));
        if max_force.is_finite() && max_force > 0.0 {
            info.max_force_n = max_force as f32;
        }
        if max_k.is_finite() && max_k > 0.0 {
            info.max_stiffness_n_per_m = (max_k * 1000.0) as f32;
        }
        Ok(Self {
            info,
            api,
            handle,
            _lib: lib,
        })
    }
}

struct Ctx<'a> {
    dev: *mut OpenHapticsDevice,
    tick: *mut (dyn FnMut(&mut dyn Device) -> bool + 'a),
    done: AtomicBool,
}

unsafe extern "C" fn servo_callback(data: *mut c_void) -> c_uint {
    // SAFETY: `data` is the `Ctx` that `run_scheduled` keeps alive, and does not touch, until
    // the scheduler has stopped; only this callback dereferences its pointers meanwhile.
    let ctx = unsafe { &*(data as *const Ctx<'_>) };
    // SAFETY: as above: exclusive use of the device and the tick closure on this thread.
    let (dev, tick) = unsafe { (&mut *ctx.dev, &mut *ctx.tick) };
    let (api, handle) = (dev.api, dev.handle);
    // SAFETY: `handle` is the initialised device; frames are balanced below.
    unsafe { (api.begin)(handle) };
    let go_on =
        std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| tick(dev))).unwrap_or(false);
    // SAFETY: closes the frame opened above.
    unsafe { (api.end)(handle) };
    if go_on {
        HD_CALLBACK_CONTINUE
    } else {
        ctx.done.store(true, Ordering::Release);
        HD_CALLBACK_DONE
    }
}

impl Device for OpenHapticsDevice {
    fn info(&self) -> &DeviceInfo {
        &self.info
    }

    fn read(&mut self, _now_ns: u64) -> Result<DeviceSample, DeviceError> {
        let (mut p, mut v, mut buttons) = ([0f64; 3], [0f64; 3], 0 as c_int);
        // SAFETY: called inside a frame; each query writes 3 doubles / 1 int into live locals.
        unsafe {
            (self.api.get_doublev)(HD_CURRENT_POSITION, p.as_mut_ptr());
            (self.api.get_doublev)(HD_CURRENT_VELOCITY, v.as_mut_ptr());
            (self.api.get_integerv)(HD_CURRENT_BUTTONS, &mut buttons);
        }
        Ok(DeviceSample {
            position: (DVec3::from_array(p) * 1e-3).as_vec3(),
            velocity: (DVec3::from_array(v) * 1e-3).as_vec3(),
            buttons: buttons as u16,
            ..DeviceSample::default()
        })
    }

    fn write_force(&mut self, force: Vec3) -> Result<(), DeviceError> {
        let f = if force.is_finite() {
            force.as_dvec3().to_array()
        } else {
            [0.0; 3]
        };
        // SAFETY: reads 3 doubles from a live local.
        unsafe { (self.api.set_doublev)(HD_CURRENT_FORCE, f.as_ptr()) };
        Ok(())
    }

    fn run_scheduled(
        &mut self,
        tick: &mut dyn FnMut(&mut dyn Device) -> bool,
    ) -> Option<Result<(), DeviceError>> {
        let api = self.api;
        let ctx = Ctx {
            dev: self as *mut Self,
            tick: tick as *mut _,
            done: AtomicBool::new(false),
        };
        // SAFETY: `ctx` outlives the scheduler (stopped before this function returns).
        let handle = unsafe {
            (api.enable)(HD_FORCE_OUTPUT);
            let h = (api.schedule)(
                servo_callback,
                &ctx as *const Ctx<'_> as *mut c_void,
                HD_MAX_SCHEDULER_PRIORITY,
            );
            (api.start)();
            h
        };
        // SAFETY: plain C call.
        let err = unsafe { (api.get_error)() };
        let result = if err.error_code != HD_SUCCESS {
            Err(DeviceError::Io(format!(
                "HD scheduler failed to start: error {:#06x}",
                err.error_code
            )))
        } else {
            while !ctx.done.load(Ordering::Acquire) {
                std::thread::sleep(Duration::from_millis(5));
            }
            Ok(())
        };
        // SAFETY: stopping the scheduler ends all callbacks before `ctx` is dropped.
        unsafe {
            (api.stop)();
            (api.unschedule)(handle);
        }
        Some(result)
    }

    fn stop(&mut self) {
        let _ = self.write_force(Vec3::ZERO);
        // SAFETY: the scheduler is stopped; the handle is ours.
        unsafe { (self.api.disable)(self.handle) };
    }
}
