//! The FMU's C API called as an importer calls it (the functions of this crate's cdylib,
//! linked here as the rlib): the lifecycle, and every misuse answered with an error status
//! and changing nothing, never a crash.

use std::ffi::{c_char, CString};
use std::ptr::{null, null_mut};

use drive_fmu::capi::*;
use drive_fmu::model::{VR_DIRECT_POSITION, VR_FOLLOWING_ERROR, VR_PARAM, VR_POSITION_SETPOINT};
use drive_fmu::package::model_guid;
use drive_physics::presets::AxisConfig;

/// A resources folder with `axis.toml` for cnc1 and its URI, and the GUID of its model.
fn resources(name: &str) -> (std::path::PathBuf, CString, CString) {
    let dir = std::env::temp_dir().join(format!("drive-fmu-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let cfg = AxisConfig::from_preset("cnc1")
        .unwrap()
        .with_override("backlash_mm", "0.05")
        .unwrap();
    let text = toml::to_string(&cfg).unwrap();
    std::fs::write(dir.join("axis.toml"), &text).unwrap();
    let uri = CString::new(format!("file://{}", dir.display())).unwrap();
    let guid = CString::new(model_guid(&cfg, &text)).unwrap();
    (dir, uri, guid)
}

unsafe fn instantiate(uri: &CString, guid: &CString) -> *mut std::ffi::c_void {
    let name = c"axis";
    unsafe {
        fmi2Instantiate(
            name.as_ptr(),
            COSIMULATION,
            guid.as_ptr(),
            uri.as_ptr(),
            null(),
            0,
            0,
        )
    }
}

unsafe fn get(c: *mut std::ffi::c_void, vr: u32) -> f64 {
    let mut v = f64::NAN;
    assert_eq!(unsafe { fmi2GetReal(c, &vr, 1, &mut v) }, OK);
    v
}

#[test]
fn an_importers_lifecycle_moves_the_axis_and_misuse_is_refused() {
    let (dir, uri, guid) = resources("life");
    unsafe {
        let c = instantiate(&uri, &guid);
        assert!(!c.is_null());
        assert_eq!(fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0), OK);
        // A step before initialisation is refused.
        assert_eq!(fmi2DoStep(c, 0.0, 1e-3, 1), ERROR);
        assert_eq!(fmi2EnterInitializationMode(c), OK);
        // Parameters may be set now; an output never; a NaN never; an unknown reference never.
        assert_eq!(fmi2SetReal(c, &VR_DIRECT_POSITION, 1, &1.0), ERROR);
        assert_eq!(fmi2SetReal(c, &VR_POSITION_SETPOINT, 1, &f64::NAN), ERROR);
        assert_eq!(fmi2SetReal(c, &12345, 1, &1.0), ERROR);
        assert_eq!(fmi2ExitInitializationMode(c), OK);
        // A ramp of 10 mm/s for 1 s in 1 ms steps: the direct encoder follows, v / k_v behind.
        let mut t = 0.0;
        for k in 1..=1000 {
            let x = 10.0 * k as f64 * 1e-3;
            assert_eq!(fmi2SetReal(c, &VR_POSITION_SETPOINT, 1, &x), OK);
            assert_eq!(fmi2DoStep(c, t, 1e-3, 1), OK, "step {k}");
            t += 1e-3;
        }
        let pos = get(c, VR_DIRECT_POSITION);
        let fe = get(c, VR_FOLLOWING_ERROR);
        assert!((9.0..10.0).contains(&pos), "direct encoder {pos} mm");
        assert!(
            (0.2..0.5).contains(&fe),
            "following error {fe} mm (v / k_v = 0.33)"
        );
        // Misuse after initialisation: a fixed parameter, a step that is not a whole number of
        // position cycles, a step from another time, a null pointer.
        let first_param = VR_PARAM;
        assert_eq!(fmi2SetReal(c, &first_param, 1, &1.0), ERROR);
        assert_eq!(fmi2DoStep(c, t, 1.5e-3, 1), DISCARD);
        assert_eq!(fmi2DoStep(c, t + 1.0, 1e-3, 1), ERROR);
        assert_eq!(fmi2DoStep(c, t, -1.0, 1), DISCARD);
        assert_eq!(fmi2DoStep(c, t, f64::INFINITY, 1), DISCARD);
        assert_eq!(fmi2GetReal(c, null(), 1, null_mut()), ERROR);
        assert_eq!(fmi2DoStep(null_mut(), 0.0, 1e-3, 1), ERROR);
        // The axis is where it was: the refused calls changed nothing.
        assert_eq!(get(c, VR_DIRECT_POSITION), pos);
        let mut last = 0.0;
        assert_eq!(fmi2GetRealStatus(c, 2, &mut last), OK);
        assert!((last - 1.0).abs() < 1e-9, "{last}");
        assert_eq!(fmi2Terminate(c), OK);
        assert_eq!(fmi2Reset(c), OK);
        assert_eq!(fmi2EnterInitializationMode(c), OK);
        assert_eq!(fmi2ExitInitializationMode(c), OK);
        assert_eq!(get(c, VR_DIRECT_POSITION), 0.0);
        fmi2FreeInstance(c);
        let v = std::ffi::CStr::from_ptr(fmi2GetVersion() as *const c_char);
        assert_eq!(v.to_str().unwrap(), "2.0");
    }
    std::fs::remove_dir_all(dir).ok();
}

#[test]
fn a_library_of_another_build_or_a_bad_resource_refuses_to_instantiate() {
    let (dir, uri, guid) = resources("refuse");
    unsafe {
        let other = CString::new("{00000000-0000-0000-0000-000000000000}").unwrap();
        assert!(instantiate(&uri, &other).is_null());
        let nowhere = CString::new("file:///nonexistent/drive-fmu").unwrap();
        assert!(instantiate(&nowhere, &guid).is_null());
        let not_a_uri = CString::new("http://example.invalid/").unwrap();
        assert!(instantiate(&not_a_uri, &guid).is_null());
        assert!(fmi2Instantiate(null(), COSIMULATION, null(), null(), null(), 0, 0).is_null());
        // Model exchange is not offered.
        let name = c"axis";
        assert!(
            fmi2Instantiate(name.as_ptr(), 0, guid.as_ptr(), uri.as_ptr(), null(), 0, 0).is_null()
        );
        // A configuration the axis cannot take.
        std::fs::write(dir.join("axis.toml"), "name = 3\n").unwrap();
        assert!(instantiate(&uri, &guid).is_null());
    }
    std::fs::remove_dir_all(dir).ok();
}

#[test]
fn resource_uris_of_either_form_and_percent_escapes_are_read() {
    assert_eq!(
        resource_path("file:///tmp/a%20b/resources").unwrap(),
        std::path::PathBuf::from("/tmp/a b/resources")
    );
    assert_eq!(
        resource_path("file:/tmp/x").unwrap(),
        std::path::PathBuf::from("/tmp/x")
    );
    assert_eq!(
        resource_path("file://localhost/tmp/x").unwrap(),
        std::path::PathBuf::from("/tmp/x")
    );
    assert!(resource_path("http://x/").is_none());
    assert!(resource_path("file:///bad%zz").is_none());
    assert!(resource_path("file:///cut%2").is_some());
}
