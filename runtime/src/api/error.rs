//! [`ApiError`]: what went wrong in a request, by kind; the command line's exit status of each
//! kind in one place ([`ApiError::exit_code`]).

use std::fmt;

use crate::infile::InputError;

/// The exit statuses of the command line (`drive-emu --help`, docs/getting-started.md); the
/// same numbers as `cli::exit`, which a test there holds equal.
pub mod status {
    /// A check failed, or the run did.
    pub const FAILED: u8 = 1;
    /// An argument or an input file's content is wrong.
    pub const USAGE: u8 = 2;
    /// An input file cannot be read.
    pub const UNREADABLE: u8 = 4;
}

/// The error of a request. Its text is the command line's message; the inner error (where
/// there is one) keeps its causes, e.g. the [`InputError`] of a file that could not be read.
#[derive(Debug)]
pub enum ApiError {
    /// What the caller gave is wrong: an argument (named as the command line spells it,
    /// `--duration`), a preset key, an override, the content of an input file.
    Invalid(anyhow::Error),
    /// An input file cannot be read: missing, not a regular file, too large, not UTF-8, or (a
    /// trace to analyse) not a trace at all.
    Unreadable(anyhow::Error),
    /// The run was stopped through its stop flag at `at_s` simulated seconds.
    Stopped { at_s: f64 },
    /// The simulation diverged: `what` names the first signal and time that was not finite;
    /// `sets` are the request's overrides (the likely cause).
    Diverged { what: String, sets: Vec<String> },
    /// The run failed otherwise.
    Failed(anyhow::Error),
}

impl ApiError {
    /// [`ApiError::Invalid`] of a message.
    pub fn invalid(msg: impl fmt::Display) -> Self {
        ApiError::Invalid(anyhow::anyhow!("{msg}"))
    }

    /// An error of what the caller gave, by its chain: [`ApiError::Unreadable`] when an input
    /// file could not be read ([`InputError`] anywhere in it), else [`ApiError::Invalid`].
    pub fn of_input(e: anyhow::Error) -> Self {
        if e.chain().any(|c| c.downcast_ref::<InputError>().is_some()) {
            ApiError::Unreadable(e)
        } else {
            ApiError::Invalid(e)
        }
    }

    /// The command line's exit status for this error: 2 what the caller gave is wrong, 4 an
    /// input file cannot be read, 1 anything else (the run failed, stopped or diverged).
    pub fn exit_code(&self) -> u8 {
        match self {
            ApiError::Invalid(_) => status::USAGE,
            ApiError::Unreadable(_) => status::UNREADABLE,
            ApiError::Stopped { .. } | ApiError::Diverged { .. } | ApiError::Failed(_) => {
                status::FAILED
            }
        }
    }

    /// The input file error in the chain, if a file could not be read.
    pub fn input_error(&self) -> Option<&InputError> {
        self.inner()?
            .chain()
            .find_map(|c| c.downcast_ref::<InputError>())
    }

    /// The inner error (none for a stopped or diverged run).
    pub fn inner(&self) -> Option<&anyhow::Error> {
        match self {
            ApiError::Invalid(e) | ApiError::Unreadable(e) | ApiError::Failed(e) => Some(e),
            ApiError::Stopped { .. } | ApiError::Diverged { .. } => None,
        }
    }

    /// The error as an [`anyhow::Error`] whose text and causes are this one's, the inner error
    /// itself where there is one (the command line marks it with its exit status).
    pub fn into_anyhow(self) -> anyhow::Error {
        match self {
            ApiError::Invalid(e) | ApiError::Unreadable(e) | ApiError::Failed(e) => e,
            other => anyhow::anyhow!("{other}"),
        }
    }
}

impl fmt::Display for ApiError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ApiError::Invalid(e) | ApiError::Unreadable(e) | ApiError::Failed(e) => {
                fmt::Display::fmt(e, f)
            }
            ApiError::Stopped { at_s } => write!(f, "stopped at {at_s:.3} simulated s"),
            ApiError::Diverged { what, sets } => write!(
                f,
                "the simulation diverged: {what}; a parameter is outside what the model \
                 resolves{}",
                if sets.is_empty() {
                    String::new()
                } else {
                    format!(
                        " (check --set {})",
                        sets.iter()
                            .map(|x| crate::quote::text(x))
                            .collect::<Vec<_>>()
                            .join(" ")
                    )
                }
            ),
        }
    }
}

impl std::error::Error for ApiError {
    /// The inner error's causes (not the inner error itself: its text is this one's).
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        self.inner()?.source()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_kind_has_its_exit_status_and_keeps_the_input_error() {
        assert_eq!(ApiError::invalid("--duration -1").exit_code(), 2);
        assert_eq!(ApiError::Stopped { at_s: 1.0 }.exit_code(), 1);
        assert_eq!(ApiError::Failed(anyhow::anyhow!("x")).exit_code(), 1);
        let missing = crate::infile::read_text(
            std::path::Path::new("/nonexistent/drive-emu-api-test"),
            "--from",
            1024,
        )
        .unwrap_err();
        let e = ApiError::of_input(anyhow::Error::new(missing).context("vendor EDS"));
        assert_eq!(e.exit_code(), 4);
        assert!(e.input_error().is_some());
        assert_eq!(e.to_string(), "vendor EDS");
        let d = ApiError::Diverged {
            what: "torque is NaN at t = 0.1 s".into(),
            sets: vec!["kv_per_s=1e9".into()],
        };
        assert_eq!(d.exit_code(), 1);
        assert!(d.to_string().contains("(check --set kv_per_s=1e9)"), "{d}");
    }
}
