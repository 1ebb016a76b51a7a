//! Command-line flags that set a parameter of the registry (`drive_physics::params`): a flag
//! is the registry key with `-` for `_` (`--kv-per-s` for `kv_per_s`, `--backlash-mm` for
//! `backlash_mm`), the key's own spelling is taken too (`--kv_per_s`), and a flag that moved
//! keeps working for one release with a one-line warning on stderr.

/// The flag of a registry key: `kv_per_s` -> `--kv-per-s`.
pub fn flag_of(key: &str) -> String {
    format!("--{}", key.replace('_', "-"))
}

/// The one-line warning for a flag that moved: "`--kv` is now `--kv-per-s`".
pub fn moved_warning(old: &str, new: &str) -> String {
    format!("drive-emu: warning: `{old}` is now `{new}` (the old name works for this release)")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_flag_is_its_key_with_dashes() {
        assert_eq!(flag_of("kv_per_s"), "--kv-per-s");
        assert_eq!(flag_of("backlash_deg"), "--backlash-deg");
        assert_eq!(
            moved_warning("--kv", "--kv-per-s"),
            "drive-emu: warning: `--kv` is now `--kv-per-s` (the old name works for this release)"
        );
    }
}
