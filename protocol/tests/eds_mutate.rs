//! Property: the EDS/DCF parser never panics on a real vendor file mangled by byte flips,
//! truncation, line shuffles, deletions and duplications; an error carries a line within the
//! file; a file it accepts resolves every value (at node ID 5) to the size of its type.
//! The fuzz target `fuzz/fuzz_targets/eds.rs` checks the same on any bytes.
use drive_protocol::od::eds_parse::{decode_text, parse};
use proptest::prelude::*;
use std::path::Path;

fn corpus() -> Vec<Vec<u8>> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/eds/vendors");
    let mut v: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| matches!(p.extension().and_then(|e| e.to_str()), Some("eds" | "dcf")))
        .collect();
    v.sort();
    v.iter().map(|p| std::fs::read(p).unwrap()).collect()
}

#[derive(Clone, Debug)]
enum Mutation {
    /// Set the byte at this fraction of the file to a value.
    Flip(f64, u8),
    /// Cut the file at this fraction.
    Truncate(f64),
    /// Swap two lines (fractions of the line count).
    Swap(f64, f64),
    /// Delete a line.
    Delete(f64),
    /// Repeat a line right after itself.
    Duplicate(f64),
    /// Put a line somewhere else.
    Move(f64, f64),
}

fn mutation() -> impl Strategy<Value = Mutation> {
    let f = 0.0f64..1.0;
    prop_oneof![
        4 => (f.clone(), prop_oneof![Just(b'='), Just(b'['), Just(b']'), Just(b'\n'), Just(b'$'), Just(b'0'), Just(b'x'), Just(0xB5u8), Just(0xFF), any::<u8>()]).prop_map(|(a, b)| Mutation::Flip(a, b)),
        1 => f.clone().prop_map(Mutation::Truncate),
        2 => (f.clone(), f.clone()).prop_map(|(a, b)| Mutation::Swap(a, b)),
        2 => f.clone().prop_map(Mutation::Delete),
        2 => f.clone().prop_map(Mutation::Duplicate),
        2 => (f.clone(), f).prop_map(|(a, b)| Mutation::Move(a, b)),
    ]
}

fn at(frac: f64, len: usize) -> usize {
    ((frac * len as f64) as usize).min(len.saturating_sub(1))
}

fn apply(mut bytes: Vec<u8>, muts: &[Mutation]) -> Vec<u8> {
    for m in muts {
        if bytes.is_empty() {
            break;
        }
        match *m {
            Mutation::Flip(p, b) => {
                let i = at(p, bytes.len());
                bytes[i] = b;
            }
            Mutation::Truncate(p) => bytes.truncate(at(p, bytes.len())),
            _ => {
                let mut lines: Vec<Vec<u8>> =
                    bytes.split(|&b| b == b'\n').map(<[u8]>::to_vec).collect();
                let n = lines.len();
                match *m {
                    Mutation::Swap(a, b) => lines.swap(at(a, n), at(b, n)),
                    Mutation::Delete(a) => {
                        lines.remove(at(a, n));
                    }
                    Mutation::Duplicate(a) => {
                        let i = at(a, n);
                        let l = lines[i].clone();
                        lines.insert(i, l);
                    }
                    Mutation::Move(a, b) => {
                        let l = lines.remove(at(a, n));
                        let j = at(b, lines.len() + 1).min(lines.len());
                        lines.insert(j, l);
                    }
                    _ => unreachable!(),
                }
                bytes = lines.join(&b'\n');
            }
        }
    }
    bytes
}

/// What must hold for any input text.
fn check(text: &str) -> Result<(), TestCaseError> {
    let lines = text.split('\n').count().max(1);
    match parse(text) {
        Err(e) => {
            prop_assert!(
                e.line >= 1 && e.line <= lines,
                "error line {} outside 1..={lines}: {e}",
                e.line
            );
            prop_assert!(!e.reason.is_empty());
        }
        Ok(f) => {
            for w in &f.warnings {
                prop_assert!(
                    w.line >= 1 && w.line <= lines,
                    "warning line {}: {w}",
                    w.line
                );
            }
            prop_assert!(f.objects.windows(2).all(|w| w[0].index < w[1].index));
            for o in &f.objects {
                prop_assert!(o.line >= 1 && o.line <= lines);
                prop_assert!(o.subs.windows(2).all(|w| w[0].sub < w[1].sub));
                for s in &o.subs {
                    for v in [&s.default, &s.parameter_value, &s.low, &s.high]
                        .into_iter()
                        .flatten()
                    {
                        let b = v.resolve(s.data_type, Some(5));
                        prop_assert!(b.is_ok(), "0x{:04X}sub{:X} {v:?}: {:?}", o.index, s.sub, b);
                        let b = b.unwrap();
                        prop_assert!(s.data_type.variable() || b.len() == s.data_type.size());
                    }
                }
            }
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 384, ..ProptestConfig::default() })]

    #[test]
    fn mangled_vendor_files_never_panic_and_errors_point_into_the_file(
        file in 0usize..64,
        muts in prop::collection::vec(mutation(), 1..6),
    ) {
        let corpus = corpus();
        let bytes = apply(corpus[file % corpus.len()].clone(), &muts);
        check(&decode_text(&bytes))?;
    }

    #[test]
    fn any_short_text_never_panics(text in "(\\[[0-9A-Fa-f]{0,4}(sub[0-9A-F]{0,3})?\\]\n|[A-Za-z]{0,12}=[-+$0-9A-Fa-fxNODEI. ]{0,14}\n|;.*\n|\r\n){0,40}") {
        check(&text)?;
    }
}
