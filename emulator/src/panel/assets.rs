//! The page and what it loads, inside the binary (no files at run time, no npm): the page,
//! its script and style, and uPlot 1.6.32 (MIT, Leon Sorokin; the `dist` files of the npm
//! package `uplot@1.6.32`, with its licence), the plotting library.

/// The page.
pub const INDEX_HTML: &[u8] = include_bytes!("web/index.html");

/// The assets under `/assets/`: name, body, content type.
pub const ASSETS: &[(&str, &[u8], &str)] = &[
    (
        "panel.js",
        include_bytes!("web/panel.js"),
        "text/javascript; charset=utf-8",
    ),
    (
        "panel.css",
        include_bytes!("web/panel.css"),
        "text/css; charset=utf-8",
    ),
    (
        "uPlot.iife.min.js",
        include_bytes!("web/uPlot.iife.min.js"),
        "text/javascript; charset=utf-8",
    ),
    (
        "uPlot.min.css",
        include_bytes!("web/uPlot.min.css"),
        "text/css; charset=utf-8",
    ),
    (
        "LICENSE-uPlot.txt",
        include_bytes!("web/LICENSE-uPlot.txt"),
        "text/plain; charset=utf-8",
    ),
];

/// The version of the vendored uPlot.
pub const UPLOT_VERSION: &str = "1.6.32";

/// An asset by name.
pub fn get(name: &str) -> Option<(&'static [u8], &'static str)> {
    ASSETS
        .iter()
        .find(|(n, _, _)| *n == name)
        .map(|(_, b, ct)| (*b, *ct))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_page_loads_only_assets_that_exist() {
        let page = std::str::from_utf8(INDEX_HTML).unwrap();
        let mut n = 0;
        for part in page.split("/assets/").skip(1) {
            let name: String = part
                .chars()
                .take_while(|c| c.is_ascii_alphanumeric() || matches!(c, '.' | '-' | '_'))
                .collect();
            assert!(get(&name).is_some(), "the page loads /assets/{name}");
            n += 1;
        }
        assert!(n >= 4, "{n}");
        let lib = std::str::from_utf8(get("uPlot.iife.min.js").unwrap().0).unwrap();
        assert!(lib.contains("uPlot"));
        let lic = std::str::from_utf8(get("LICENSE-uPlot.txt").unwrap().0).unwrap();
        assert!(lic.contains("MIT License") && lic.contains("Leon Sorokin"));
    }
}
