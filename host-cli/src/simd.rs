//! `EMBER_SIMD`: which instructions the kernel's ray queries may use (`ember_kernel::simd`).
//!
//! `auto` (or unset): AVX where the CPU has it, the build's baseline otherwise. `baseline`:
//! the baseline only, for benchmarks of the dispatch itself and for checking that both give
//! the same images. No value changes a result.

/// The environment variable read by [`apply_env`].
pub const VAR: &str = "EMBER_SIMD";

/// Applies `EMBER_SIMD` to the kernel, once at start-up.
///
/// # Errors
/// A value other than `auto` or `baseline`, named with the variable.
pub fn apply_env() -> Result<(), String> {
    match std::env::var(VAR) {
        Err(std::env::VarError::NotPresent) => Ok(()),
        Ok(v) if v == "auto" => Ok(()),
        Ok(v) if v == "baseline" => {
            #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
            ember_kernel::simd::limit_to_baseline();
            Ok(())
        }
        Ok(v) => Err(format!("{VAR}={v:?}: expected \"auto\" or \"baseline\"")),
        Err(e) => Err(format!("{VAR}: {e}")),
    }
}

/// What the ray queries run with in this process: `"avx"` or `"baseline"`.
#[must_use]
pub fn in_use() -> &'static str {
    #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
    if ember_kernel::simd::Avx::detect().is_some() {
        return "avx";
    }
    "baseline"
}
