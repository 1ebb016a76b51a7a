//! `drive-emu profiles`: the quirk profiles shipped in the binary and the switches of schema 1
//! (docs/quirks.md), as `drive_protocol::Quirks::SWITCHES` describes them; with a profile
//! (name or path), what it resolves to; `--markdown`: docs/quirks.md's table of switches.

use crate::drive::quirk_profile::{list_text, QuirkProfile};
use anyhow::Result;
use clap::Args;
use drive_protocol::Quirks;

#[derive(Args, Debug, Clone)]
pub struct ProfilesArgs {
    /// Show what this profile (a name, or a path to a .toml file) turns on, after `extends`,
    /// and check it; without it, list the profiles and the switches.
    #[arg(value_name = "NAME|PATH")]
    pub profile: Option<String>,
    /// Print the table of switches of docs/quirks.md section 4 (markdown), generated from the
    /// switches' one description.
    #[arg(long, conflicts_with = "profile")]
    pub markdown: bool,
}

pub fn run(args: &ProfilesArgs) -> Result<()> {
    if args.markdown {
        print!(
            "{}",
            drive_protocol::quirks::schema::markdown(Quirks::SWITCHES)
        );
        return Ok(());
    }
    let Some(p) = &args.profile else {
        print!("{}", list_text()?);
        return Ok(());
    };
    let b = QuirkProfile::resolve(Some(p), None, &[])?;
    println!(
        "profile {} (extends: {})",
        b.profile.as_deref().unwrap_or(p),
        b.chain.join(" -> ")
    );
    for s in Quirks::SWITCHES {
        let on = b.quirks.is_on(s.name);
        println!(
            "  {} {}",
            if on { "on " } else { "off" },
            b.quirks.describe(s.name)
        );
    }
    let id = &b.identity;
    let ms = |v: Option<u32>| v.map_or("-".into(), |v| format!("{v} ms"));
    println!(
        "  identity: boot_delay {} (reset node {}, reset communication {})",
        ms(id.boot_delay_ms),
        ms(id.reset_node_boot_delay_ms),
        ms(id.reset_communication_boot_delay_ms)
    );
    for (index, sub, key, v) in id.objects() {
        println!("  identity: {key} 0x{index:04X}:{sub} = 0x{v:08X}");
    }
    if let Some(n) = &id.device_name {
        println!("  identity: device_name 0x1008 = \"{n}\"");
    }
    Ok(())
}
