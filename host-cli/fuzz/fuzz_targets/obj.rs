//! Bytes -> OBJ parse, validation, kernel buffers, emitter table, BVH
//! (`ember_cli::fuzzing::obj`); every `mtllib` reads the Cornell box MTL.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = ember_cli::fuzzing::obj(data, ember_cli::fuzzing::CORNELL_MTL);
});
