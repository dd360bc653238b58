//! `EMBER_SIMD`: which instructions the kernel's ray queries may use (`ember_kernel::simd`).
//!
//! `auto` (or unset): AVX-512 or AVX2 where the CPU has it, the build's baseline otherwise.
//! `avx2`: at most AVX2 (eight lanes), for measuring what AVX-512 buys, for comparisons at an
//! AVX2 machine's width, and for CPUs that slow their clock for 512-bit instructions.
//! `baseline`: the baseline only, for benchmarks of the dispatch itself and for checking that
//! all give the same images. No value changes a result.

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
        Ok(v) if v == "avx2" => {
            #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
            ember_kernel::simd::limit_to_avx2();
            Ok(())
        }
        Ok(v) if v == "baseline" => {
            #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
            ember_kernel::simd::limit_to_baseline();
            Ok(())
        }
        Ok(v) => Err(format!(
            "{VAR}={v:?}: expected \"auto\", \"avx2\" or \"baseline\""
        )),
        Err(e) => Err(format!("{VAR}: {e}")),
    }
}

/// What the ray queries run with in this process: `"avx512"`, `"avx"` or `"baseline"`.
#[must_use]
pub fn in_use() -> &'static str {
    #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
    if ember_kernel::simd::Avx512::detect().is_some() {
        return "avx512";
    }
    #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
    if ember_kernel::simd::Avx::detect().is_some() {
        return "avx";
    }
    "baseline"
}

/// This machine's CPU model, its SIMD flags and the ray queries' lanes, for every printed
/// figure (`Intel(R) Xeon(R) Processor; SIMD sse4_2 avx avx2 fma avx512f; ray queries in avx
/// lanes`). The model and flags come from `/proc/cpuinfo` (Linux; "unknown CPU" elsewhere).
#[must_use]
pub fn cpu_summary() -> String {
    const FLAGS: [&str; 9] = [
        "sse4_2", "avx", "avx2", "fma", "avx512f", "avx512dq", "avx512bw", "avx512vl", "asimd",
    ];
    let info = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
    let field = |name: &str| {
        info.lines()
            .find(|l| l.split(':').next().is_some_and(|k| k.trim() == name))
            .and_then(|l| l.split_once(':'))
            .map(|(_, v)| v.trim().to_string())
    };
    let model = field("model name").unwrap_or_else(|| "unknown CPU".into());
    let flags = field("flags")
        .or_else(|| field("Features"))
        .unwrap_or_default();
    let have: Vec<&str> = FLAGS
        .iter()
        .copied()
        .filter(|f| flags.split_whitespace().any(|g| g == *f))
        .collect();
    format!(
        "{model}; SIMD {}; ray queries in {} lanes",
        if have.is_empty() {
            "none listed".to_string()
        } else {
            have.join(" ")
        },
        in_use()
    )
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_summary_names_the_lanes_in_use() {
        let s = super::cpu_summary();
        assert!(
            s.ends_with(&format!("ray queries in {} lanes", super::in_use())),
            "{s}"
        );
        assert!(s.contains("; SIMD "), "{s}");
    }
}
