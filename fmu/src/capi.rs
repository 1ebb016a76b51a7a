//! The FMI 2.0 co-simulation C API (fmi2Functions.h) over [`Instance`]. Every function checks
//! its pointers, never unwinds into the caller (a panic becomes fmi2Fatal) and reports a
//! refused call through the importer's logger with the reason.

#![allow(non_snake_case, clippy::missing_safety_doc)]

use std::ffi::{c_char, c_void, CStr, CString};
use std::panic::{catch_unwind, AssertUnwindSafe};

use drive_physics::presets::AxisConfig;

use crate::model::{Instance, Phase};

/// fmi2Status.
pub type Status = i32;
/// fmi2OK.
pub const OK: Status = 0;
/// fmi2Warning.
pub const WARNING: Status = 1;
/// fmi2Discard.
pub const DISCARD: Status = 2;
/// fmi2Error.
pub const ERROR: Status = 3;
/// fmi2Fatal.
pub const FATAL: Status = 4;

/// fmi2Type: co-simulation.
pub const COSIMULATION: i32 = 1;

type Logger =
    unsafe extern "C" fn(*mut c_void, *const c_char, Status, *const c_char, *const c_char, ...);

/// fmi2CallbackFunctions.
#[repr(C)]
pub struct CallbackFunctions {
    /// fmi2CallbackLogger.
    pub logger: Option<Logger>,
    /// fmi2CallbackAllocateMemory (not used: canNotUseMemoryManagementFunctions).
    pub allocate_memory: Option<unsafe extern "C" fn(usize, usize) -> *mut c_void>,
    /// fmi2CallbackFreeMemory.
    pub free_memory: Option<unsafe extern "C" fn(*mut c_void)>,
    /// fmi2StepFinished.
    pub step_finished: Option<unsafe extern "C" fn(*mut c_void, Status)>,
    /// fmi2ComponentEnvironment.
    pub component_environment: *mut c_void,
}

/// What an fmi2Component points at.
pub struct Component {
    instance: Instance,
    name: CString,
    logger: Option<Logger>,
    environment: *mut c_void,
    last_status: Status,
}

impl Component {
    fn log(&self, status: Status, message: &str) {
        if let Some(logger) = self.logger {
            let msg = CString::new(message.replace('\0', " ")).unwrap_or_default();
            let category = c"drive-emu";
            // SAFETY: the importer gave us this logger; "%s" with a C string.
            unsafe {
                logger(
                    self.environment,
                    self.name.as_ptr(),
                    status,
                    category.as_ptr(),
                    c"%s".as_ptr(),
                    msg.as_ptr(),
                )
            };
        }
    }
}

/// Run `f` on the component behind `c`: null is an error, a panic is fatal.
unsafe fn with(c: *mut c_void, f: impl FnOnce(&mut Component) -> Status) -> Status {
    if c.is_null() {
        return ERROR;
    }
    // SAFETY: `c` came from fmi2Instantiate (a Box<Component>) and is not freed yet: the FMI
    // standard's contract with the importer.
    let comp = unsafe { &mut *(c as *mut Component) };
    match catch_unwind(AssertUnwindSafe(|| f(comp))) {
        Ok(s) => {
            comp.last_status = s;
            s
        }
        Err(_) => {
            comp.instance.phase = Phase::Error;
            FATAL
        }
    }
}

/// The path of a `file://` resource location (percent-decoded).
pub fn resource_path(uri: &str) -> Option<std::path::PathBuf> {
    let rest = uri
        .strip_prefix("file://")
        .map(|r| {
            // file://host/path or file:///path
            if r.starts_with('/') {
                r.to_string()
            } else {
                r.find('/').map_or(String::new(), |i| r[i..].to_string())
            }
        })
        .or_else(|| uri.strip_prefix("file:").map(str::to_string))?;
    let bytes = rest.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' && i + 2 < bytes.len() {
            let hex = std::str::from_utf8(&bytes[i + 1..i + 3]).ok()?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    Some(std::path::PathBuf::from(String::from_utf8(out).ok()?))
}

/// Largest `resources/axis.toml` read, bytes.
const MAX_CONFIG_BYTES: u64 = 1 << 20;

/// The configuration in the FMU's resources, and the GUID this library gives it.
fn load_config(resource_location: &str) -> Result<(AxisConfig, String), String> {
    let dir = resource_path(resource_location)
        .ok_or_else(|| format!("resource location `{resource_location}` is not a file URI"))?;
    let path = dir.join("axis.toml");
    let meta = std::fs::metadata(&path).map_err(|e| format!("{}: {e}", path.display()))?;
    if !meta.is_file() || meta.len() > MAX_CONFIG_BYTES {
        return Err(format!(
            "{}: not a regular file of at most {MAX_CONFIG_BYTES} bytes",
            path.display()
        ));
    }
    let text = std::fs::read_to_string(&path).map_err(|e| format!("{}: {e}", path.display()))?;
    let cfg = AxisConfig::from_toml(&text).map_err(|e| format!("{}: {e}", path.display()))?;
    let guid = crate::package::model_guid(&cfg, &text);
    Ok((cfg, guid))
}

unsafe fn str_arg<'a>(p: *const c_char) -> Option<&'a str> {
    if p.is_null() {
        None
    } else {
        // SAFETY: a NUL-terminated string from the importer.
        unsafe { CStr::from_ptr(p) }.to_str().ok()
    }
}

#[no_mangle]
pub extern "C" fn fmi2GetTypesPlatform() -> *const c_char {
    c"default".as_ptr()
}

#[no_mangle]
pub extern "C" fn fmi2GetVersion() -> *const c_char {
    c"2.0".as_ptr()
}

#[no_mangle]
pub unsafe extern "C" fn fmi2Instantiate(
    instance_name: *const c_char,
    fmu_type: i32,
    guid: *const c_char,
    resource_location: *const c_char,
    functions: *const CallbackFunctions,
    _visible: i32,
    _logging_on: i32,
) -> *mut c_void {
    let r = catch_unwind(|| {
        // SAFETY: pointers from the importer, checked for null.
        let (name, location, given_guid) = unsafe {
            (
                str_arg(instance_name),
                str_arg(resource_location),
                str_arg(guid),
            )
        };
        let (logger, environment) = if functions.is_null() {
            (None, std::ptr::null_mut())
        } else {
            // SAFETY: non-null, the importer's struct.
            let f = unsafe { &*functions };
            (f.logger, f.component_environment)
        };
        let mut comp = Component {
            instance: Instance::new(AxisConfig::from_preset("cnc1").ok()?),
            name: CString::new(name.unwrap_or("drive_emu_axis")).ok()?,
            logger,
            environment,
            last_status: OK,
        };
        if fmu_type != COSIMULATION {
            comp.log(ERROR, "this FMU is for co-simulation only");
            return None;
        }
        match location.map(load_config) {
            Some(Ok((_, ours))) if given_guid != Some(ours.as_str()) => {
                comp.log(
                    ERROR,
                    &format!(
                        "GUID {} of the model description is not this library's ({ours}): \
                         the FMU's shared library was built from another drive-emu",
                        given_guid.unwrap_or("(none)")
                    ),
                );
                return None;
            }
            Some(Ok((cfg, _))) => comp.instance = Instance::new(cfg),
            Some(Err(e)) => {
                comp.log(ERROR, &e);
                return None;
            }
            None => {
                comp.log(ERROR, "no resource location");
                return None;
            }
        }
        Some(Box::into_raw(Box::new(comp)) as *mut c_void)
    });
    r.ok().flatten().unwrap_or(std::ptr::null_mut())
}

#[no_mangle]
pub unsafe extern "C" fn fmi2FreeInstance(c: *mut c_void) {
    if !c.is_null() {
        // SAFETY: from fmi2Instantiate, freed once (the importer's contract).
        drop(unsafe { Box::from_raw(c as *mut Component) });
    }
}

#[no_mangle]
pub unsafe extern "C" fn fmi2SetDebugLogging(
    c: *mut c_void,
    _on: i32,
    _n: usize,
    _categories: *const *const c_char,
) -> Status {
    unsafe { with(c, |_| OK) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi2SetupExperiment(
    c: *mut c_void,
    _tolerance_defined: i32,
    _tolerance: f64,
    start_time: f64,
    _stop_time_defined: i32,
    _stop_time: f64,
) -> Status {
    unsafe {
        with(c, |comp| {
            if start_time != 0.0 {
                comp.log(WARNING, "the axis starts at time 0 whatever the start time");
                return WARNING;
            }
            OK
        })
    }
}

#[no_mangle]
pub unsafe extern "C" fn fmi2EnterInitializationMode(c: *mut c_void) -> Status {
    unsafe {
        with(c, |comp| {
            if comp.instance.phase != Phase::Instantiated {
                comp.log(ERROR, "enter initialisation mode: not just instantiated");
                return ERROR;
            }
            comp.instance.phase = Phase::Initialization;
            OK
        })
    }
}

#[no_mangle]
pub unsafe extern "C" fn fmi2ExitInitializationMode(c: *mut c_void) -> Status {
    unsafe {
        with(c, |comp| {
            if comp.instance.phase != Phase::Initialization {
                comp.log(
                    ERROR,
                    "exit initialisation mode: not in initialisation mode",
                );
                return ERROR;
            }
            match comp.instance.initialize() {
                Ok(()) => OK,
                Err(e) => {
                    comp.instance.phase = Phase::Error;
                    comp.log(ERROR, &e.0);
                    ERROR
                }
            }
        })
    }
}

#[no_mangle]
pub unsafe extern "C" fn fmi2Terminate(c: *mut c_void) -> Status {
    unsafe {
        with(c, |comp| {
            comp.instance.phase = Phase::Terminated;
            OK
        })
    }
}

#[no_mangle]
pub unsafe extern "C" fn fmi2Reset(c: *mut c_void) -> Status {
    unsafe {
        with(c, |comp| {
            comp.instance.reset();
            OK
        })
    }
}

/// Read `n` values through `get` into `out`.
unsafe fn get_values<T>(
    c: *mut c_void,
    vr: *const u32,
    n: usize,
    out: *mut T,
    conv: impl Fn(f64) -> T,
) -> Status {
    unsafe {
        with(c, |comp| {
            if n == 0 {
                return OK;
            }
            if vr.is_null() || out.is_null() {
                return ERROR;
            }
            // SAFETY: arrays of `n` from the importer.
            let (vrs, outs) = (
                std::slice::from_raw_parts(vr, n),
                std::slice::from_raw_parts_mut(out, n),
            );
            for (r, o) in vrs.iter().zip(outs) {
                match comp.instance.get(*r) {
                    Ok(v) => *o = conv(v),
                    Err(e) => {
                        comp.log(ERROR, &e.0);
                        return ERROR;
                    }
                }
            }
            OK
        })
    }
}

/// Write `n` values from `values` through `set`.
unsafe fn set_values<T: Copy>(
    c: *mut c_void,
    vr: *const u32,
    n: usize,
    values: *const T,
    conv: impl Fn(T) -> f64,
) -> Status {
    unsafe {
        with(c, |comp| {
            if n == 0 {
                return OK;
            }
            if vr.is_null() || values.is_null() {
                return ERROR;
            }
            // SAFETY: arrays of `n` from the importer.
            let (vrs, vals) = (
                std::slice::from_raw_parts(vr, n),
                std::slice::from_raw_parts(values, n),
            );
            for (r, v) in vrs.iter().zip(vals) {
                if let Err(e) = comp.instance.set(*r, conv(*v)) {
                    comp.log(ERROR, &e.0);
                    return ERROR;
                }
            }
            OK
        })
    }
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetReal(
    c: *mut c_void,
    vr: *const u32,
    n: usize,
    v: *mut f64,
) -> Status {
    unsafe { get_values(c, vr, n, v, |x| x) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetInteger(
    c: *mut c_void,
    vr: *const u32,
    n: usize,
    v: *mut i32,
) -> Status {
    unsafe { get_values(c, vr, n, v, |x| x as i32) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetBoolean(
    c: *mut c_void,
    vr: *const u32,
    n: usize,
    v: *mut i32,
) -> Status {
    unsafe { get_values(c, vr, n, v, |x| i32::from(x != 0.0)) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetString(
    c: *mut c_void,
    _vr: *const u32,
    n: usize,
    _v: *mut *const c_char,
) -> Status {
    unsafe { with(c, |_| if n == 0 { OK } else { ERROR }) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi2SetReal(
    c: *mut c_void,
    vr: *const u32,
    n: usize,
    v: *const f64,
) -> Status {
    unsafe { set_values(c, vr, n, v, |x| x) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi2SetInteger(
    c: *mut c_void,
    vr: *const u32,
    n: usize,
    v: *const i32,
) -> Status {
    unsafe { set_values(c, vr, n, v, f64::from) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi2SetBoolean(
    c: *mut c_void,
    vr: *const u32,
    n: usize,
    v: *const i32,
) -> Status {
    unsafe { set_values(c, vr, n, v, |x| f64::from(u8::from(x != 0))) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi2SetString(
    c: *mut c_void,
    _vr: *const u32,
    n: usize,
    _v: *const *const c_char,
) -> Status {
    unsafe { with(c, |_| if n == 0 { OK } else { ERROR }) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetFMUstate(c: *mut c_void, _s: *mut *mut c_void) -> Status {
    unsafe { with(c, |_| ERROR) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi2SetFMUstate(c: *mut c_void, _s: *mut c_void) -> Status {
    unsafe { with(c, |_| ERROR) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi2FreeFMUstate(c: *mut c_void, _s: *mut *mut c_void) -> Status {
    unsafe { with(c, |_| ERROR) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi2SerializedFMUstateSize(
    c: *mut c_void,
    _s: *mut c_void,
    _n: *mut usize,
) -> Status {
    unsafe { with(c, |_| ERROR) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi2SerializeFMUstate(
    c: *mut c_void,
    _s: *mut c_void,
    _b: *mut u8,
    _n: usize,
) -> Status {
    unsafe { with(c, |_| ERROR) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi2DeSerializeFMUstate(
    c: *mut c_void,
    _b: *const u8,
    _n: usize,
    _s: *mut *mut c_void,
) -> Status {
    unsafe { with(c, |_| ERROR) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetDirectionalDerivative(
    c: *mut c_void,
    _u: *const u32,
    _nu: usize,
    _k: *const u32,
    _nk: usize,
    _dk: *const f64,
    _du: *mut f64,
) -> Status {
    unsafe { with(c, |_| ERROR) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi2SetRealInputDerivatives(
    c: *mut c_void,
    _vr: *const u32,
    _n: usize,
    _order: *const i32,
    _v: *const f64,
) -> Status {
    unsafe { with(c, |_| ERROR) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetRealOutputDerivatives(
    c: *mut c_void,
    _vr: *const u32,
    _n: usize,
    _order: *const i32,
    _v: *mut f64,
) -> Status {
    unsafe { with(c, |_| ERROR) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi2DoStep(
    c: *mut c_void,
    current: f64,
    h: f64,
    _no_prior_state: i32,
) -> Status {
    unsafe {
        with(c, |comp| {
            if comp.instance.phase != Phase::StepMode {
                comp.log(ERROR, "do step: not initialised (or terminated, or failed)");
                return ERROR;
            }
            if (current - comp.instance.time_s()).abs() > 1e-9 * current.abs().max(1.0) {
                comp.log(
                    ERROR,
                    &format!(
                        "do step at {current} s: the axis is at {} s (no rollback)",
                        comp.instance.time_s()
                    ),
                );
                return ERROR;
            }
            match comp.instance.do_step(h) {
                Ok(()) => OK,
                Err(e) => {
                    comp.log(ERROR, &e.0);
                    if comp.instance.phase == Phase::Error {
                        ERROR
                    } else {
                        DISCARD
                    }
                }
            }
        })
    }
}

#[no_mangle]
pub unsafe extern "C" fn fmi2CancelStep(c: *mut c_void) -> Status {
    unsafe { with(c, |_| ERROR) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetStatus(c: *mut c_void, _kind: i32, s: *mut Status) -> Status {
    unsafe {
        with(c, |comp| {
            if s.is_null() {
                return ERROR;
            }
            // SAFETY: non-null out-pointer from the importer.
            *s = comp.last_status;
            OK
        })
    }
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetRealStatus(c: *mut c_void, kind: i32, v: *mut f64) -> Status {
    unsafe {
        with(c, |comp| {
            // fmi2LastSuccessfulTime = 2
            if v.is_null() || kind != 2 {
                return DISCARD;
            }
            *v = comp.instance.time_s();
            OK
        })
    }
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetIntegerStatus(c: *mut c_void, _kind: i32, _v: *mut i32) -> Status {
    unsafe { with(c, |_| DISCARD) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetBooleanStatus(c: *mut c_void, _kind: i32, _v: *mut i32) -> Status {
    unsafe { with(c, |_| DISCARD) }
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetStringStatus(
    c: *mut c_void,
    _kind: i32,
    _v: *mut *const c_char,
) -> Status {
    unsafe { with(c, |_| DISCARD) }
}
