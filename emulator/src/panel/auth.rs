//! Who may use the panel: with a token, every request under `/api/` must carry it (header
//! `Authorization: Bearer TOKEN`, or `X-Panel-Token: TOKEN`, or the query `?token=TOKEN`, which
//! the page and `EventSource` use); without one, the panel listens on loopback only
//! ([`super::check_bind`]). Compared in constant time.

use anyhow::{bail, Result};

/// The environment variable a token may come from (not visible in `ps`, unlike an argument).
pub const TOKEN_ENV: &str = "DRIVE_EMU_PANEL_TOKEN";

/// Where the token came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TokenSource {
    Env,
    File,
    CommandLine,
}

/// The panel's token from the one source given: `--panel-token-file FILE` (its first line),
/// the environment variable [`TOKEN_ENV`] (`env`), or `--panel-token` (then `warn` is told
/// that every user of the machine can read it with `ps`). Two sources at once are an error.
pub fn resolve_token(
    arg: Option<&str>,
    file: Option<&std::path::Path>,
    env: Option<std::ffi::OsString>,
) -> Result<Option<(String, TokenSource)>> {
    let env = env.filter(|v| !v.is_empty());
    let given = [arg.is_some(), file.is_some(), env.is_some()];
    if given.iter().filter(|g| **g).count() > 1 {
        bail!(
            "the panel's token comes from one of --panel-token-file, {TOKEN_ENV} and \
             --panel-token; {} given",
            [
                (given[1], "--panel-token-file"),
                (given[2], TOKEN_ENV),
                (given[0], "--panel-token")
            ]
            .iter()
            .filter(|(g, _)| *g)
            .map(|(_, n)| *n)
            .collect::<Vec<_>>()
            .join(" and ")
        );
    }
    let (token, source) = if let Some(path) = file {
        let text = crate::infile::read_text(path, "--panel-token-file", 4096)?;
        let line = text.lines().next().unwrap_or("").trim().to_string();
        (line, TokenSource::File)
    } else if let Some(v) = env {
        let Some(v) = v.to_str() else {
            bail!("{TOKEN_ENV}: not UTF-8");
        };
        (v.trim().to_string(), TokenSource::Env)
    } else if let Some(t) = arg {
        (t.to_string(), TokenSource::CommandLine)
    } else {
        return Ok(None);
    };
    check_token_text(&token).map_err(|e| {
        let from = match source {
            TokenSource::Env => TOKEN_ENV,
            TokenSource::File => "--panel-token-file",
            TokenSource::CommandLine => "--panel-token",
        };
        anyhow::anyhow!("{}", e.to_string().replacen("--panel-token", from, 1))
    })?;
    Ok(Some((token, source)))
}

/// What `--panel-token` on the command line prints on stderr.
pub const COMMAND_LINE_WARNING: &str = "drive-emu: warning: --panel-token on the command line \
    is visible to every user of this machine (ps, /proc/PID/cmdline): give it in the \
    environment variable DRIVE_EMU_PANEL_TOKEN or in a file (--panel-token-file FILE)";

/// The token a run was started with, if any.
#[derive(Debug, Clone, Default)]
pub struct Auth {
    token: Option<String>,
}

/// Longest token accepted, bytes (it travels in a header and a URL).
pub const MAX_TOKEN_LEN: usize = 256;

/// A token must be 1..=256 visible ASCII characters without `&`, `#`, `%` or `+` (it goes into
/// URLs as is).
pub fn check_token_text(t: &str) -> Result<()> {
    if t.is_empty() || t.len() > MAX_TOKEN_LEN {
        bail!("--panel-token: must be 1 to {MAX_TOKEN_LEN} characters");
    }
    if let Some(c) = t
        .chars()
        .find(|c| !c.is_ascii_graphic() || matches!(c, '&' | '#' | '%' | '+'))
    {
        bail!(
            "--panel-token: {c:?} is not allowed (letters, digits and visible ASCII punctuation \
             other than & # % +)"
        );
    }
    Ok(())
}

/// Equal in time independent of where the first difference is.
fn same(a: &[u8], b: &[u8]) -> bool {
    if a.len() != b.len() {
        return false;
    }
    a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

/// The token a request offered: `Authorization: Bearer T`, `X-Panel-Token: T`, or `token=T`
/// in the query.
pub fn offered<'a>(headers: &'a axum::http::HeaderMap, query: Option<&'a str>) -> Option<&'a str> {
    let h = |name: &str| headers.get(name).and_then(|v| v.to_str().ok());
    // The scheme is case-insensitive (RFC 9110 11.1): `Bearer`, `bearer`, `BEARER`.
    if let Some(t) = h("authorization")
        .and_then(|v| v.trim_start().split_once(' '))
        .filter(|(scheme, _)| scheme.eq_ignore_ascii_case("bearer"))
        .map(|(_, t)| t)
    {
        return Some(t.trim());
    }
    if let Some(t) = h("x-panel-token") {
        return Some(t.trim());
    }
    query?.split('&').find_map(|kv| kv.strip_prefix("token="))
}

impl Auth {
    pub fn new(token: Option<String>) -> Self {
        Auth { token }
    }

    /// Whether a token is required.
    pub fn required(&self) -> bool {
        self.token.is_some()
    }

    /// `Ok` when no token is required or the request offered the right one; the error is the
    /// reason to send back.
    pub fn check(&self, offered: Option<&str>) -> Result<(), &'static str> {
        match (&self.token, offered) {
            (None, _) => Ok(()),
            (Some(_), None) => Err("this panel needs its token: header `Authorization: Bearer \
                                    TOKEN` or query `?token=TOKEN`"),
            (Some(t), Some(o)) if same(t.as_bytes(), o.as_bytes()) => Ok(()),
            (Some(_), Some(_)) => Err("wrong token"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use axum::http::{HeaderMap, HeaderValue};

    #[test]
    fn a_token_is_checked_wherever_it_is_offered() {
        let a = Auth::new(Some("s3cret-Token".into()));
        assert!(a.required());
        assert!(a.check(None).is_err());
        assert_eq!(a.check(Some("s3cret-Tokem")), Err("wrong token"));
        assert_eq!(a.check(Some("s3cret")), Err("wrong token"));
        assert!(a.check(Some("s3cret-Token")).is_ok());
        let mut h = HeaderMap::new();
        assert_eq!(offered(&h, Some("a=1&token=abc&b=2")), Some("abc"));
        assert_eq!(offered(&h, Some("a=1")), None);
        h.insert("x-panel-token", HeaderValue::from_static("xyz"));
        assert_eq!(offered(&h, Some("token=abc")), Some("xyz"));
        h.insert("authorization", HeaderValue::from_static("Bearer tok"));
        assert_eq!(offered(&h, None), Some("tok"));
        for v in ["bearer tok", "BEARER tok", "bEaReR  tok "] {
            h.insert("authorization", HeaderValue::from_static(v));
            assert_eq!(offered(&h, None), Some("tok"), "{v}");
        }
        h.remove("x-panel-token");
        h.insert("authorization", HeaderValue::from_static("Basic dG9r"));
        assert_eq!(offered(&h, None), None);
        // Without a token configured, anything passes (the panel is on loopback then).
        assert!(Auth::new(None).check(None).is_ok());
    }

    #[test]
    fn the_token_comes_from_one_source() {
        let env = |s: &str| Some(std::ffi::OsString::from(s));
        let (t, src) = resolve_token(None, None, env("envtok")).unwrap().unwrap();
        assert_eq!((t.as_str(), src), ("envtok", TokenSource::Env));
        let (t, src) = resolve_token(Some("cli"), None, None).unwrap().unwrap();
        assert_eq!((t.as_str(), src), ("cli", TokenSource::CommandLine));
        assert!(resolve_token(None, None, None).unwrap().is_none());
        assert!(resolve_token(None, None, env("")).unwrap().is_none());
        let e = resolve_token(Some("cli"), None, env("envtok")).unwrap_err();
        assert!(
            e.to_string()
                .contains("DRIVE_EMU_PANEL_TOKEN and --panel-token"),
            "{e}"
        );
        let e = resolve_token(None, None, env("a b")).unwrap_err();
        assert!(e.to_string().starts_with("DRIVE_EMU_PANEL_TOKEN: "), "{e}");
        let dir = std::env::temp_dir().join(format!("panel-token-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let f = dir.join("token");
        std::fs::write(&f, "filetok\n").unwrap();
        let (t, src) = resolve_token(None, Some(&f), None).unwrap().unwrap();
        assert_eq!((t.as_str(), src), ("filetok", TokenSource::File));
        let e = resolve_token(None, Some(std::path::Path::new("/dev/zero")), None).unwrap_err();
        assert!(e.to_string().contains("a character device"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn token_text_is_checked_at_start() {
        assert!(check_token_text("abc-DEF_123.~").is_ok());
        for bad in ["", "a b", "a&b", "a#b", "a%b", "a+b", "ä"] {
            assert!(check_token_text(bad).is_err(), "{bad:?}");
        }
        assert!(check_token_text(&"x".repeat(257)).is_err());
    }

    #[test]
    fn a_non_loopback_address_needs_a_token() {
        let e = super::super::check_bind("0.0.0.0:8080", None).unwrap_err();
        let msg = e.to_string();
        assert!(
            msg.contains("not a loopback address") && msg.contains("--panel-token"),
            "{msg}"
        );
        assert!(super::super::check_bind("192.168.1.10:8080", None).is_err());
        assert!(super::super::check_bind("[::]:8080", None).is_err());
        assert!(super::super::check_bind("0.0.0.0:8080", Some("tok")).is_ok());
        assert!(super::super::check_bind("127.0.0.1:8080", None).is_ok());
        assert!(super::super::check_bind("[::1]:8080", None).is_ok());
        assert!(super::super::check_bind("127.0.0.2:0", None).is_ok());
        let e = super::super::check_bind("localhost", None).unwrap_err();
        assert!(e.to_string().contains("not an address with a port"), "{e}");
        assert!(super::super::check_bind("0.0.0.0:1", Some("a b")).is_err());
    }
}
