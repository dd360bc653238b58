//! Bytes -> `SceneFile::parse_bytes` -> camera (`ember_cli::fuzzing::scene_toml`).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = ember_cli::fuzzing::scene_toml(data);
});
