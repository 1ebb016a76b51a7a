//! The live panel in a build without it (the cargo feature `panel` off: no HTTP server, no
//! axum, tokio or hyper in the binary, as in the Python module's wheel). The options are
//! still parsed, so that `--panel` is refused with a clear error instead of being unknown or
//! ignored; nothing can start a panel, so [`Panel`] and [`PanelLoop`] have no values.

use crate::bus::fault::FaultyBus;
use crate::bus::CanBus;
use crate::drive::axis_drive::AxisDrive;
use crate::presets::AxisConfig;
use crate::runtime::Runtime;
use crate::scenario::live::{LiveLink, LoopInjector};
use anyhow::{bail, Result};
use std::path::PathBuf;
use std::sync::Arc;

/// Where the panel would listen when `--panel` is given without an address.
pub const DEFAULT_ADDR: &str = "127.0.0.1:8080";

/// The error of `--panel` in this build.
pub const NOT_BUILT: &str = "--panel: this drive-emu was built without the live panel (the \
cargo feature `panel`, on by default): build it with the default features, e.g. `cargo \
install --path emulator`";

/// The panel's command-line options: accepted, and refused with [`NOT_BUILT`] when given.
#[derive(clap::Args, Debug, Clone, Default)]
pub struct PanelArgs {
    /// The live panel: not in this build (the cargo feature `panel` is off).
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = DEFAULT_ADDR)]
    pub panel: Option<String>,
    /// The panel's token: not in this build.
    #[arg(long, value_name = "TOKEN", requires = "panel")]
    pub panel_token: Option<String>,
    /// The panel's token file: not in this build.
    #[arg(long, value_name = "FILE", requires = "panel")]
    pub panel_token_file: Option<PathBuf>,
    /// The panel's recording directory: not in this build.
    #[arg(long, value_name = "DIR", requires = "panel")]
    pub panel_dir: Option<PathBuf>,
}

/// `--panel` given: the error that this build has no panel.
pub fn check_args(args: &PanelArgs) -> Result<()> {
    if args.panel.is_some() {
        bail!("{NOT_BUILT}");
    }
    Ok(())
}

/// One axis as the panel would show it.
#[derive(Debug, Clone)]
pub struct PanelAxis {
    pub node_id: u8,
    pub preset: String,
    pub config: AxisConfig,
    pub overrides: Vec<(String, String)>,
}

/// The run's fieldbus (which bus faults the panel would offer).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PanelBus {
    #[default]
    Can,
    Ethercat,
}

/// What the panel would need to know of the run.
#[derive(Debug, Clone)]
pub struct PanelSetup {
    pub axes: Vec<PanelAxis>,
    pub bus: PanelBus,
    pub iface: Option<String>,
    pub tick_hz: u32,
    pub lockstep: bool,
    pub master_id: u8,
    pub json_stdout: bool,
}

/// A running panel: none in this build.
pub enum Panel {}

impl Panel {
    pub fn url(&self) -> String {
        match *self {}
    }

    pub fn clients(&self) -> usize {
        match *self {}
    }

    pub fn stop(self) {
        match self {}
    }
}

/// The loop's half of a panel: none in this build.
pub enum PanelLoop {}

impl PanelLoop {
    pub fn attach_scenario(&mut self, _link: Arc<LiveLink>, _master_id: u8) {
        match *self {}
    }

    pub fn on_tick<B: CanBus>(&mut self, _rt: &mut Runtime<FaultyBus<B>, AxisDrive>) {
        match *self {}
    }

    pub fn on_ethercat_cycle(
        &mut self,
        _seg: &mut drive_ethercat::Segment,
        _drives: &mut [AxisDrive],
        _faults: &mut crate::bus::ethercat::EcatFaults,
        _now_us: u64,
    ) {
        match *self {}
    }
}

/// What the panel would need of a live run's options.
pub struct RunContext<'a> {
    pub bus: PanelBus,
    pub iface: Option<&'a str>,
    pub node: u8,
    pub lockstep: bool,
    pub json: bool,
    pub machine: &'a crate::drive::machine::MachineFile,
    pub scenario: Option<&'a crate::scenario::Scenario>,
}

/// `run --panel`: [`NOT_BUILT`]; without `--panel`, nothing.
pub fn start_for_run(
    args: &PanelArgs,
    _run: RunContext<'_>,
    _bus: (&Arc<LiveLink>, &Arc<crate::observe::Observation>),
    _injector: &mut Option<LoopInjector>,
) -> Result<Option<(Panel, PanelLoop)>> {
    check_args(args)?;
    Ok(None)
}

/// `demo --panel`: [`NOT_BUILT`]; without `--panel`, nothing.
pub fn start(
    args: &PanelArgs,
    _setup: PanelSetup,
    _obs: Arc<crate::observe::Observation>,
) -> Result<Option<(Panel, PanelLoop)>> {
    check_args(args)?;
    Ok(None)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn panel_is_refused_with_the_reason_and_nothing_else_is() {
        assert!(check_args(&PanelArgs::default()).is_ok());
        let e = check_args(&PanelArgs {
            panel: Some(DEFAULT_ADDR.into()),
            ..PanelArgs::default()
        })
        .unwrap_err();
        assert!(
            e.to_string().contains("built without the live panel"),
            "{e}"
        );
    }
}
