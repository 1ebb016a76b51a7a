//! The `.fmu` file: `modelDescription.xml` (from the parameter registry, through
//! [`crate::model::variables`]), `binaries/linux64/drive_emu_axis.so` (this crate as a cdylib)
//! and `resources/axis.toml` (the axis the instance builds).

use std::fmt::Write as _;
use std::io::Write as _;

use drive_physics::presets::AxisConfig;

use crate::model::{variables, Causality, Kind, Variable};

/// The model identifier: the shared library's name inside the FMU and the model's name.
pub const MODEL_IDENTIFIER: &str = "drive_emu_axis";

/// The FMU's shared library as cargo leaves it in a target directory `dir` (`target/<profile>`):
/// the newer of `dir/libdrive_fmu.so` and `dir/deps/libdrive_fmu.so` (a build of this crate as
/// a dependency only refreshes the latter).
pub fn library_in(dir: &std::path::Path) -> Option<std::path::PathBuf> {
    [
        dir.join("libdrive_fmu.so"),
        dir.join("deps/libdrive_fmu.so"),
    ]
    .into_iter()
    .filter_map(|p| Some((std::fs::metadata(&p).ok()?.modified().ok()?, p)))
    .max()
    .map(|(_, p)| p)
}

/// The communication step the FMU proposes (`DefaultExperiment stepSize`), s.
pub const DEFAULT_STEP_S: f64 = 1e-3;

fn xml_escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            c if (c as u32) < 0x20 => out.push(' '),
            c => out.push(c),
        }
    }
    out
}

/// The GUID of the FMU of a configuration (`cfg_text`, its TOML) and of this library's
/// variables: the same axis and the same model give the same GUID, and a shared library whose
/// variables differ from the model description's (another build) refuses to instantiate.
pub fn model_guid(cfg: &AxisConfig, cfg_text: &str) -> String {
    let mut signature = String::from(cfg_text);
    for v in variables(cfg) {
        let _ = write!(
            signature,
            "|{}:{}:{:?}:{:?}",
            v.vr, v.name, v.causality, v.kind
        );
    }
    guid(&signature)
}

/// A GUID of a text: its FNV-1a hashes.
pub fn guid(cfg_text: &str) -> String {
    let mut a: u64 = 0xcbf2_9ce4_8422_2325;
    let mut b: u64 = 0x8422_2325_cbf2_9ce4;
    for byte in cfg_text.bytes() {
        a = (a ^ u64::from(byte)).wrapping_mul(0x0000_0100_0000_01b3);
        b = (b ^ u64::from(byte).rotate_left(3)).wrapping_mul(0x0000_0100_0000_01b3);
    }
    format!(
        "{{{:08x}-{:04x}-{:04x}-{:04x}-{:012x}}}",
        a >> 32,
        (a >> 16) & 0xffff,
        a & 0xffff,
        b >> 48,
        b & 0xffff_ffff_ffff
    )
}

fn scalar(v: &Variable) -> String {
    let causality = match v.causality {
        Causality::Input => "input",
        Causality::Output => "output",
        Causality::Parameter => "parameter",
    };
    let (variability, initial) = match v.causality {
        Causality::Input => ("continuous", ""),
        Causality::Output => ("continuous", " initial=\"calculated\""),
        Causality::Parameter => ("fixed", " initial=\"exact\""),
    };
    let body = match (v.kind, v.causality) {
        (Kind::Boolean, _) => format!("<Boolean start=\"{}\"/>", v.start != 0.0),
        (Kind::Real, Causality::Output) => format!("<Real unit=\"{}\"/>", xml_escape(v.unit)),
        (Kind::Real, _) => format!(
            "<Real start=\"{:?}\"{}/>",
            v.start,
            if v.unit.is_empty() || v.unit == "-" {
                String::new()
            } else {
                format!(" unit=\"{}\"", xml_escape(v.unit))
            }
        ),
    };
    format!(
        "    <ScalarVariable name=\"{}\" valueReference=\"{}\" causality=\"{causality}\" \
         variability=\"{variability}\"{initial} description=\"{}\">\n      {body}\n    \
         </ScalarVariable>\n",
        xml_escape(&v.name),
        v.vr,
        xml_escape(&v.description),
    )
}

/// The model description of the FMU for `cfg` (`cfg_text`: its TOML, for the GUID).
pub fn model_description(cfg: &AxisConfig, cfg_text: &str) -> String {
    let vars = variables(cfg);
    let mut units: Vec<&str> = vars
        .iter()
        .filter(|v| v.kind == Kind::Real && !v.unit.is_empty() && v.unit != "-")
        .map(|v| v.unit)
        .collect();
    units.sort_unstable();
    units.dedup();
    let mut x = String::new();
    let _ = write!(
        x,
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n\
         <fmiModelDescription fmiVersion=\"2.0\" modelName=\"{MODEL_IDENTIFIER}\" guid=\"{}\" \
         description=\"{}\" generationTool=\"drive-emu {}\" variableNamingConvention=\"flat\" \
         numberOfEventIndicators=\"0\">\n  \
         <CoSimulation modelIdentifier=\"{MODEL_IDENTIFIER}\" \
         canHandleVariableCommunicationStepSize=\"true\" canNotUseMemoryManagementFunctions=\"true\" \
         canGetAndSetFMUstate=\"false\" canSerializeFMUstate=\"false\"/>\n  <UnitDefinitions>\n",
        model_guid(cfg, cfg_text),
        xml_escape(&format!(
            "drive-emu's simulated CNC axis `{}` ({}): motor, backlash, stiffness, friction, \
             two encoders, the servo cascade",
            cfg.name, cfg.description
        )),
        env!("CARGO_PKG_VERSION"),
    );
    for u in &units {
        let _ = writeln!(x, "    <Unit name=\"{}\"/>", xml_escape(u));
    }
    let _ = write!(
        x,
        "  </UnitDefinitions>\n  <DefaultExperiment startTime=\"0.0\" stopTime=\"10.0\" \
         stepSize=\"{DEFAULT_STEP_S:?}\"/>\n  <ModelVariables>\n"
    );
    for v in &vars {
        x.push_str(&scalar(v));
    }
    x.push_str("  </ModelVariables>\n  <ModelStructure>\n    <Outputs>\n");
    let outputs: Vec<usize> = vars
        .iter()
        .enumerate()
        .filter(|(_, v)| v.causality == Causality::Output)
        .map(|(i, _)| i + 1)
        .collect();
    for i in &outputs {
        let _ = writeln!(x, "      <Unknown index=\"{i}\"/>");
    }
    x.push_str("    </Outputs>\n    <InitialUnknowns>\n");
    for i in &outputs {
        let _ = writeln!(x, "      <Unknown index=\"{i}\"/>");
    }
    x.push_str("    </InitialUnknowns>\n  </ModelStructure>\n</fmiModelDescription>\n");
    x
}

/// Write the `.fmu` (a zip) for `cfg` with `library` (the bytes of this crate's cdylib for
/// linux64) to `out`.
pub fn write_fmu(
    cfg: &AxisConfig,
    library: &[u8],
    out: impl std::io::Write + std::io::Seek,
) -> Result<(), String> {
    let cfg_text = toml::to_string(cfg).map_err(|e| format!("axis configuration: {e}"))?;
    let description = model_description(cfg, &cfg_text);
    let mut zip = zip::ZipWriter::new(out);
    let opts = zip::write::SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Deflated)
        .unix_permissions(0o644);
    let files: [(String, &[u8]); 3] = [
        ("modelDescription.xml".into(), description.as_bytes()),
        (format!("binaries/linux64/{MODEL_IDENTIFIER}.so"), library),
        ("resources/axis.toml".into(), cfg_text.as_bytes()),
    ];
    for (name, bytes) in files {
        zip.start_file(name.as_str(), opts)
            .map_err(|e| format!("{name}: {e}"))?;
        zip.write_all(bytes).map_err(|e| format!("{name}: {e}"))?;
    }
    zip.finish()
        .map_err(|e| format!("finishing the FMU: {e}"))?;
    Ok(())
}
