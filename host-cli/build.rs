//! Hashes the sources that turn scene data into a GI bake (the kernel and the baker) into
//! `EMBER_BAKE_CODE_HASH`, so a stored bake made by other code is never reused. The scene data
//! itself (whatever the loader made of the files) is hashed at run time (`bake::provenance`),
//! so the loader's sources need not be part of this hash.

use std::path::Path;

fn hash_dir(dir: &Path, h: &mut u64) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    let mut paths: Vec<_> = entries.filter_map(|e| e.ok().map(|e| e.path())).collect();
    paths.sort();
    for p in paths {
        if p.is_dir() {
            hash_dir(&p, h);
        } else if p.extension().is_some_and(|e| e == "rs") {
            println!("cargo:rerun-if-changed={}", p.display());
            for b in std::fs::read(&p).unwrap_or_default() {
                // FNV-1a
                *h ^= u64::from(b);
                *h = h.wrapping_mul(0x0100_0000_01b3);
            }
        }
    }
}

fn main() {
    let manifest = std::env::var("CARGO_MANIFEST_DIR").unwrap_or_default();
    let root = Path::new(&manifest);
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    hash_dir(&root.join("../kernel/src"), &mut h);
    let bake = root.join("src/bake.rs");
    println!("cargo:rerun-if-changed={}", bake.display());
    for b in std::fs::read(&bake).unwrap_or_default() {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    println!("cargo:rustc-env=EMBER_BAKE_CODE_HASH={h:016x}");
}
