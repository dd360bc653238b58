//! ember's C API as a static library: the kernel built with its `capi` feature, whose
//! `extern "C"` functions (`ember_*`, declared in kernel/include/ember.h) this archive exports.
//! Link it with the system libraries a Rust static library needs on the target (on Linux:
//! `-lpthread -ldl -lm`; `cargo rustc -p ember-capi -- --print native-static-libs` lists them).

pub use ember_kernel::capi::*;
