//! The instruction sets hemi's vector copies may use: what the CPU has, less AVX-512 when the
//! environment variable `HEMI_NO_AVX512` is `1`, so that the copies an AVX2-only CPU runs
//! (eight-lane packets, the AVX2 loops) can be run, tested and timed on a CPU with both.

/// Whether the AVX-512 copies may run: the CPU has AVX-512F (and POPCNT, which they use too
/// and every such CPU has) and `HEMI_NO_AVX512` is not `1` (checked once).
#[cfg(target_arch = "x86_64")]
pub(crate) fn avx512() -> bool {
    static YES: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *YES.get_or_init(|| {
        let off = std::env::var("HEMI_NO_AVX512").is_ok_and(|v| v.trim() == "1");
        !off && std::arch::is_x86_feature_detected!("avx512f") && std::arch::is_x86_feature_detected!("popcnt")
    })
}
