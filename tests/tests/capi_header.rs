//! The committed C API header (kernel/include/ember.h) is what cbindgen generates from the
//! kernel's `capi` module today. `EMBER_BLESS=1` writes it instead of comparing.

use std::path::Path;

#[test]
fn committed_header_matches_cbindgen() {
    let kernel = Path::new(env!("CARGO_MANIFEST_DIR")).join("../kernel");
    let config = cbindgen::Config::from_file(kernel.join("cbindgen.toml"))
        .expect("cannot read kernel/cbindgen.toml");
    let bindings = cbindgen::Builder::new()
        .with_config(config)
        .with_src(kernel.join("src/capi.rs"))
        .generate()
        .expect("cbindgen cannot generate the header");
    let mut generated = Vec::new();
    bindings.write(&mut generated);
    let generated = String::from_utf8(generated).expect("header is UTF-8");
    let path = kernel.join("include/ember.h");
    if std::env::var_os("EMBER_BLESS").is_some() {
        std::fs::write(&path, &generated).expect("cannot write kernel/include/ember.h");
        return;
    }
    let committed = std::fs::read_to_string(&path).unwrap_or_default();
    if committed != generated {
        let line = committed
            .lines()
            .zip(generated.lines())
            .position(|(a, b)| a != b)
            .unwrap_or_else(|| committed.lines().count().min(generated.lines().count()));
        panic!(
            "kernel/include/ember.h is out of date with kernel/src/capi.rs (first difference at \
             line {}):\n  committed: {:?}\n  generated: {:?}\nRegenerate it with \
             `EMBER_BLESS=1 cargo test -p ember-tests --test capi_header` and commit it.",
            line + 1,
            committed.lines().nth(line).unwrap_or("<end of file>"),
            generated.lines().nth(line).unwrap_or("<end of file>"),
        );
    }
}
