//! One exit status per kind of outcome, the same for every command (docs/getting-started.md,
//! "Exit status", and `drive-emu --help`):
//!
//! | status | kind |
//! |---|---|
//! | 0 | done (a verdict given, a run ended) |
//! | 1 | a check failed (a scenario's expectation, `analyze --fail-on-backlash`), or the run failed (the bus, the system) |
//! | 2 | what the user wrote is wrong: an argument, or the content of an input file (with file, line and key) |
//! | 3 | inconclusive (`analyze`: nothing could be measured) |
//! | 4 | an input file cannot be read (missing, not a regular file, too large, not UTF-8) |
//!
//! Clap's own argument errors exit 2 as well. An error becomes a usage error (2) by passing
//! through [`usage`]; an unreadable input file is an [`crate::infile::InputError`] anywhere in
//! the error's chain (4); anything else is 1.

use std::fmt;

/// Exit status: a check failed, or the run did.
pub const FAILED: u8 = 1;
/// Exit status: an argument or an input file's content is wrong.
pub const USAGE: u8 = 2;
/// Exit status: `analyze` could not measure anything.
pub const INCONCLUSIVE: u8 = 3;
/// Exit status: an input file cannot be read.
pub const UNREADABLE: u8 = 4;

/// The table for `--help`.
pub const HELP: &str = "Exit status: 0 done; 1 a check failed (a scenario's expectation, \
--fail-on-backlash) or the run failed (bus, system); 2 an argument or an input file's content is \
wrong; 3 inconclusive (analyze); 4 an input file cannot be read.";

/// An error marked with its exit status `STATUS`; its text is the inner error's, which is
/// its source (a message printer skips a cause it has already printed).
#[derive(Debug)]
pub struct Marked<const STATUS: u8>(anyhow::Error);

/// An error in what the user wrote (exit status 2).
pub type Usage = Marked<USAGE>;
/// An input file that could not be read, where the error is only a message (exit status 4).
pub type Unreadable = Marked<UNREADABLE>;

impl<const STATUS: u8> fmt::Display for Marked<STATUS> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(&self.0, f)
    }
}

impl<const STATUS: u8> std::error::Error for Marked<STATUS> {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        Some(self.0.as_ref())
    }
}

/// Mark `e` as an error in what the user wrote: exit status 2, unless an input file could
/// not be read at all (4).
pub fn usage(e: impl Into<anyhow::Error>) -> anyhow::Error {
    let e = e.into();
    if e.downcast_ref::<Usage>().is_some() {
        return e;
    }
    anyhow::Error::new(Marked::<USAGE>(e))
}

/// Mark `e` as an input file that could not be read: exit status 4.
pub fn unreadable(e: impl Into<anyhow::Error>) -> anyhow::Error {
    anyhow::Error::new(Marked::<UNREADABLE>(e.into()))
}

/// A scenario file's error: 4 when it could not be read (no line), else 2.
pub fn scenario_file(e: crate::scenario::ScenarioError) -> anyhow::Error {
    if e.line == 0 {
        unreadable(e)
    } else {
        usage(e)
    }
}

/// The error of building something from what the user wrote (a machine's axis from its
/// preset, overrides and vendor file), said with `prefix`: 4 where a file could not be read,
/// else 2.
pub fn config(prefix: impl fmt::Display, err: anyhow::Error) -> anyhow::Error {
    let e = anyhow::anyhow!("{prefix}: {err:#}");
    if code_of(&err) == UNREADABLE {
        unreadable(e)
    } else {
        usage(e)
    }
}

/// [`usage`] of a message.
pub fn usage_msg(msg: impl fmt::Display) -> anyhow::Error {
    usage(anyhow::anyhow!("{msg}"))
}

/// The exit status of an error: 4 when an input file could not be read, 2 for a usage
/// error, else 1.
pub fn code_of(e: &anyhow::Error) -> u8 {
    let unreadable = e.chain().any(|c| {
        c.downcast_ref::<crate::infile::InputError>().is_some()
            || c.downcast_ref::<Unreadable>().is_some()
    });
    if unreadable {
        UNREADABLE
    } else if e.chain().any(|c| {
        c.downcast_ref::<Usage>().is_some()
            || c.downcast_ref::<crate::api::analyze::UsageError>()
                .is_some()
    }) {
        USAGE
    } else {
        FAILED
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_kind_has_its_status_through_context_and_wrapping() {
        assert_eq!(code_of(&anyhow::anyhow!("the bus is down")), FAILED);
        assert_eq!(code_of(&usage_msg("--node 0: outside 1..=127")), USAGE);
        let u = usage_msg("--node 0").context("run");
        assert_eq!(code_of(&u), USAGE);
        assert_eq!(u.to_string(), "run");
        let missing = crate::infile::read_text(
            std::path::Path::new("/nonexistent/drive-emu-exit-test"),
            "--eds",
            1024,
        )
        .unwrap_err();
        let e = anyhow::Error::new(missing).context("axis node 5");
        assert_eq!(code_of(&e), UNREADABLE);
        // still 4 when marked as usage: the file was never read
        assert_eq!(code_of(&usage(e)), UNREADABLE);
        // the text is the inner error's, its causes stay in the chain
        let u = usage(anyhow::anyhow!("inner").context("outer"));
        assert_eq!(u.to_string(), "outer");
        assert!(u.chain().any(|c| c.to_string() == "inner"));
    }
}
