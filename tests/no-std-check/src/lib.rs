//! A `#![no_std]`, `#![no_main]` static library with its own panic handler and no global
//! allocator that links ember's kernel and renders with it. Built for `x86_64-unknown-none`,
//! a target that has no `std` and no `alloc` at all, so it compiles only if nothing in the
//! kernel (or glam, or libm) needs them. scripts/determinism.sh also links it into a small C
//! program on the host and checks that it renders the determinism scene bit for bit
//! (x86_64-unknown-none does its float arithmetic in software: no SSE).
#![no_std]
#![no_main]

// On hosted targets cargo's workspace commands (`cargo test --workspace`, clippy) build this
// crate with panic = "unwind", whose runtime only std provides; there std is linked for that
// alone. x86_64-unknown-none has no std to link: that build is the proof.
#[cfg(not(target_os = "none"))]
extern crate std;

use ember_kernel::bvh::max_nodes;

/// Hash of the pixels of the determinism path-traced renders (implicit, explicit, MIS).
// `no_mangle` counts as unsafe code (symbol clashes); the export needs its plain name.
#[allow(unsafe_code)]
#[no_mangle]
pub extern "C" fn ember_nostd_render_hash() -> u64 {
    ember_determinism::render_hash(&ember_determinism::Scene::new().view())
}

/// Hash of the determinism bake.
#[allow(unsafe_code)]
#[no_mangle]
pub extern "C" fn ember_nostd_bake_hash() -> u64 {
    ember_determinism::bake_hash(&ember_determinism::Scene::new().view())
}

/// Hash of the determinism splatting renders (light tracer, BDPT power and balance).
#[allow(unsafe_code)]
#[no_mangle]
pub extern "C" fn ember_nostd_splat_hash() -> u64 {
    ember_determinism::splat_hash(&ember_determinism::Scene::new().view())
}

/// BVH node capacity for `triangles` triangles (a kernel call without floats).
#[allow(unsafe_code)]
#[no_mangle]
pub extern "C" fn ember_nostd_max_nodes(triangles: u32) -> u32 {
    max_nodes(triangles as usize) as u32
}

/// Without std nobody else provides one. A panic spins: there is nothing to return to.
#[cfg(target_os = "none")]
#[panic_handler]
fn panic(_: &core::panic::PanicInfo<'_>) -> ! {
    loop {
        core::hint::spin_loop();
    }
}
