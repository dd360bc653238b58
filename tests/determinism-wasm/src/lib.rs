//! The determinism scene as a WebAssembly module: no std, no allocation, no wasm-bindgen.
//! Node.js instantiates it with the WebAssembly API (scripts/determinism.sh) and calls
//! `ember_render_hash`, `ember_bake_hash` and `ember_splat_hash`, which return the FNV-1a
//! hashes (as BigInt) of exactly what `ember-determinism` computes on the host.
#![cfg_attr(target_arch = "wasm32", no_std)]

/// Hash of the pixels of the three renders (implicit, explicit, MIS).
// `no_mangle` counts as unsafe code (symbol clashes); the export needs its plain name.
#[allow(unsafe_code)]
#[no_mangle]
pub extern "C" fn ember_render_hash() -> u64 {
    ember_determinism::render_hash(&ember_determinism::Scene::new().view())
}

/// Hash of the baked values (MIS, then explicit).
// `no_mangle` counts as unsafe code (symbol clashes); the export needs its plain name.
#[allow(unsafe_code)]
#[no_mangle]
pub extern "C" fn ember_bake_hash() -> u64 {
    ember_determinism::bake_hash(&ember_determinism::Scene::new().view())
}

/// Hash of the pixels of the three splatting renders (light tracer, BDPT power and balance),
/// their splats in fixed-size buffers on the module's stack.
// `no_mangle` counts as unsafe code (symbol clashes); the export needs its plain name.
#[allow(unsafe_code)]
#[no_mangle]
pub extern "C" fn ember_splat_hash() -> u64 {
    ember_determinism::splat_hash(&ember_determinism::Scene::new().view())
}

/// A panic in the module traps (`unreachable`); Node reports it as a RuntimeError.
#[cfg(target_arch = "wasm32")]
#[panic_handler]
fn panic(_: &core::panic::PanicInfo<'_>) -> ! {
    core::arch::wasm32::unreachable()
}
