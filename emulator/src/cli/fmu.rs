//! `drive-emu fmu`: the preset axis (with `--set` overrides) as an FMI 2.0 co-simulation FMU
//! (crate `drive-fmu`): modelDescription.xml from the parameter registry, the FMU's shared
//! library for linux64, the axis configuration as its resource.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::Args;

use crate::presets::AxisConfig;

/// Arguments of `drive-emu fmu`.
#[derive(Args, Debug)]
pub struct FmuArgs {
    /// Axis preset (cnc1 ... cnc5).
    #[arg(long, default_value = "cnc1")]
    pub preset: String,
    /// Override a preset key, e.g. --set backlash_mm=0.05 (repeatable): the FMU's parameters
    /// start at these values.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// Where to write the FMU.
    #[arg(short = 'o', long = "output", value_name = "FILE")]
    pub output: PathBuf,
    /// The FMU's shared library (crate drive-fmu built as a cdylib: `cargo build --release -p
    /// drive-fmu`). Default: `libdrive_fmu.so` beside this program, as cargo builds them.
    #[arg(long, value_name = "FILE")]
    pub library: Option<PathBuf>,
}

/// The shared library beside the running program (`target/<profile>/`, as cargo builds them).
fn default_library() -> Option<PathBuf> {
    let exe = std::env::current_exe().ok()?;
    drive_fmu::package::library_in(exe.parent()?)
}

/// Largest shared library taken, bytes.
const MAX_LIBRARY_BYTES: u64 = 512 << 20;

fn read_library(path: &Path) -> Result<Vec<u8>> {
    let meta = std::fs::metadata(path).with_context(|| format!("--library {}", path.display()))?;
    if !meta.is_file() || meta.len() > MAX_LIBRARY_BYTES {
        bail!(
            "--library {}: not a regular file of at most {} MB",
            path.display(),
            MAX_LIBRARY_BYTES >> 20
        );
    }
    let bytes = std::fs::read(path).with_context(|| format!("--library {}", path.display()))?;
    if !bytes.starts_with(b"\x7fELF") {
        bail!("--library {}: not an ELF shared library", path.display());
    }
    Ok(bytes)
}

/// Run `drive-emu fmu`.
pub fn fmu(args: &FmuArgs) -> Result<()> {
    let cfg = AxisConfig::from_preset(&args.preset)
        .and_then(|c| c.with_overrides(args.set.iter().map(String::as_str)))
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let lib = match &args.library {
        Some(p) => p.clone(),
        None => default_library().context(
            "the FMU's shared library libdrive_fmu.so is not beside drive-emu: build it with \
             `cargo build --release -p drive-fmu`, or name it with --library",
        )?,
    };
    let bytes = read_library(&lib)?;
    let file = std::fs::File::create(&args.output)
        .with_context(|| format!("-o {}", args.output.display()))?;
    drive_fmu::package::write_fmu(&cfg, &bytes, std::io::BufWriter::new(file))
        .map_err(|e| anyhow::anyhow!("-o {}: {e}", args.output.display()))?;
    let vars = drive_fmu::model::variables(&cfg);
    eprintln!(
        "wrote {} ({} `{}`: {} variables, co-simulation, linux64, step {} s by default)",
        args.output.display(),
        drive_fmu::package::MODEL_IDENTIFIER,
        cfg.name,
        vars.len(),
        drive_fmu::package::DEFAULT_STEP_S
    );
    Ok(())
}
