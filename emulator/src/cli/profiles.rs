//! `drive-emu profiles`: the vendor behaviour profiles shipped in the binary and the switches
//! of schema 1 (docs/quirks.md); with a profile (name or path), what it resolves to.

use crate::drive::profile::{describe_switch, list_text, Behaviour, SWITCHES};
use anyhow::Result;
use clap::Args;

#[derive(Args, Debug, Clone)]
pub struct ProfilesArgs {
    /// Show what this profile (a name, or a path to a .toml file) turns on, after `extends`,
    /// and check it; without it, list the profiles and the switches.
    #[arg(value_name = "NAME|PATH")]
    pub profile: Option<String>,
}

pub fn run(args: &ProfilesArgs) -> Result<()> {
    let Some(p) = &args.profile else {
        print!("{}", list_text()?);
        return Ok(());
    };
    let b = Behaviour::resolve(Some(p), None, &[])?;
    println!(
        "profile {} (extends: {})",
        b.profile.as_deref().unwrap_or(p),
        b.chain.join(" -> ")
    );
    for s in SWITCHES {
        let on = b.quirks.is_on(s.name);
        println!(
            "  {} {}",
            if on { "on " } else { "off" },
            if on {
                describe_switch(&b.quirks, s.name)
            } else {
                s.name.to_string()
            }
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
