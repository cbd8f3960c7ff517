//! The instruction sets hemi's vector copies may use: what the CPU has, less AVX-512 when the
//! environment variable `HEMI_NO_AVX512` is `1`, so that the copies an AVX2-only CPU runs
//! (eight-lane packets, the AVX2 loops) can be run, tested and timed on a CPU with both.

/// Whether the eight-lane copies may run: the CPU has x86-64-v3's AVX2, FMA, BMI1, BMI2, LZCNT
/// and POPCNT (every Intel CPU since Haswell, every AMD since Zen), which they are compiled for
/// (checked once). Bit scans and counts of lane masks then take one instruction each.
#[cfg(target_arch = "x86_64")]
pub(crate) fn avx2() -> bool {
    static YES: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *YES.get_or_init(|| {
        std::arch::is_x86_feature_detected!("avx2")
            && std::arch::is_x86_feature_detected!("fma")
            && std::arch::is_x86_feature_detected!("bmi1")
            && std::arch::is_x86_feature_detected!("bmi2")
            && std::arch::is_x86_feature_detected!("lzcnt")
            && std::arch::is_x86_feature_detected!("popcnt")
    })
}

/// Whether the AVX-512 copies may run: the CPU has AVX-512F and everything [`avx2`] asks for
/// (which they are compiled with too, and every such CPU has), and `HEMI_NO_AVX512` is not `1`
/// (checked once).
#[cfg(target_arch = "x86_64")]
pub(crate) fn avx512() -> bool {
    static YES: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *YES.get_or_init(|| {
        let off = std::env::var("HEMI_NO_AVX512").is_ok_and(|v| v.trim() == "1");
        !off && std::arch::is_x86_feature_detected!("avx512f") && avx2()
    })
}

/// Rays per packet on this CPU and environment: sixteen where [`avx512`] allows, eight
/// otherwise (what eight-wide trees trace, and the width the cosine table is laid out in).
#[cfg(target_arch = "x86_64")]
pub(crate) fn packet_lanes() -> usize {
    if avx512() { 16 } else { 8 }
}
