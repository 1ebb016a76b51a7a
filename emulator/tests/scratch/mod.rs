//! A scratch directory per test thread under the temp directory, removed when the test's
//! thread ends (shared by the tests that write files for the CLI).

use std::path::PathBuf;

struct Scratch(PathBuf);

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

thread_local! {
    static SCRATCH: Scratch = Scratch(std::env::temp_dir().join(
        format!("drive-emu-test-{}-{:?}", std::process::id(), std::thread::current().id())
            .replace(['(', ')'], ""),
    ));
}

/// `name` in this test's scratch directory (created on first use).
pub fn path(name: &str) -> PathBuf {
    SCRATCH.with(|d| {
        std::fs::create_dir_all(&d.0).expect("scratch dir");
        d.0.join(name)
    })
}
