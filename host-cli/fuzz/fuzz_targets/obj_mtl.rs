//! `OBJ \0 MTL` -> as the `obj` target, with every `mtllib` reading the MTL part.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let (obj, mtl) = ember_cli::fuzzing::split_obj_mtl(data);
    let _ = ember_cli::fuzzing::obj(obj, mtl);
});
