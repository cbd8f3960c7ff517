//! hemi's SIMD layer: which instruction sets the vector copies may use, the tokens that prove
//! it, and the lane types they are written over.
//!
//! The instruction set is detected here and nowhere else: what the CPU has, less AVX-512 when
//! the environment variable `HEMI_NO_AVX512` is `1` (so that the copies an AVX2-only CPU runs
//! can be run, tested and timed on a CPU with both), and none at all when `HEMI_SIMD` is
//! `portable` (the eight-lane kernels then run in the portable lanes). Only this module makes
//! the tokens ([`HasAvx2`], [`HasAvx512`], [`Plain`]) that let code run a set's instructions.
//!
//! Lane types of f32 ([`Lanes`]) are eight lanes in an AVX register ([`Avx`]), sixteen in an
//! AVX-512 one ([`Avx512`]), or eight in plain arrays ([`Portable`], no intrinsics; the reference
//! the other two are tested against); of u32, `U32Lanes` for the samplers' hashes, paired with
//! the f32 lanes of the same width by `SampleLanes`.
//! Kernels are written once, generic over the lane type, and compiled per instruction set in
//! functions marked `#[target_feature]`: a closure or generic function only inlines into code
//! compiled for the same instruction set. [`multiversion!`] generates such copies and their
//! dispatch for plain loops the compiler vectorises.

mod lanes;
mod portable;
mod token;

#[cfg(target_arch = "x86_64")]
pub(crate) mod avx;
#[cfg(target_arch = "x86_64")]
pub(crate) mod avx512;
#[cfg(target_arch = "x86_64")]
mod u32_lanes;

#[cfg(target_arch = "x86_64")]
pub(crate) use avx::Avx;
#[cfg(target_arch = "x86_64")]
pub(crate) use avx512::Avx512;
pub(crate) use lanes::{BitLanes, CompressLanes, FusedLanes, Lanes};
#[cfg(target_arch = "x86_64")]
pub(crate) use lanes::{SampleLanes, dot3};
pub(crate) use portable::Portable;
pub(crate) use token::Plain;
#[cfg(target_arch = "x86_64")]
pub(crate) use token::{Eight, HasAvx2, HasAvx512};
#[cfg(target_arch = "x86_64")]
pub(crate) use u32_lanes::U32Lanes;

/// Asks the CPU to start loading `x`'s cache lines (a hint; no effect on results).
#[inline(always)]
pub(crate) fn prefetch<T>(x: &T) {
    #[cfg(target_arch = "x86_64")]
    {
        let p = (x as *const T).cast::<i8>();
        for line in (0..std::mem::size_of::<T>()).step_by(64) {
            // SAFETY: a prefetch never faults, and `line` stays inside `x`.
            unsafe { std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(p.add(line)) };
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = x;
}

/// Asks the CPU to start loading every cache line that `x`'s elements touch (a hint).
#[inline(always)]
pub(crate) fn prefetch_slice<T>(x: &[T]) {
    #[cfg(target_arch = "x86_64")]
    {
        let p = x.as_ptr().cast::<i8>();
        let bytes = std::mem::size_of_val(x);
        // The first byte of each line from the slice's start, and its last byte's line.
        for at in (0..bytes).step_by(64).chain(bytes.checked_sub(1)) {
            // SAFETY: a prefetch never faults, and `at` stays inside `x`.
            unsafe { std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(p.add(at)) };
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = x;
}

/// The time-stamp counter, read once every earlier instruction has completed (LFENCE), so that
/// work issued before a reading is not counted after it.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(crate) fn fenced_timestamp() -> u64 {
    // SAFETY: every x86_64 CPU has LFENCE (SSE2) and RDTSC, and neither has another effect.
    unsafe {
        std::arch::x86_64::_mm_lfence();
        std::arch::x86_64::_rdtsc()
    }
}

/// An instruction set hemi's vector copies are compiled for, from least to most.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Isa {
    /// No vector instruction set: the portable code (any target, or `HEMI_SIMD=portable`).
    Portable,
    /// x86-64-v3: AVX2, FMA, BMI1, BMI2, LZCNT and POPCNT (every Intel CPU since Haswell,
    /// every AMD since Zen). Bit scans and counts of lane masks take one instruction each.
    Avx2,
    /// AVX-512F on top of [`Isa::Avx2`].
    Avx512,
}

/// The best instruction set this CPU has, whatever the environment says (checked once). The
/// only place hemi asks the CPU.
pub fn cpu_isa() -> Isa {
    #[cfg(target_arch = "x86_64")]
    {
        static ISA: std::sync::OnceLock<Isa> = std::sync::OnceLock::new();
        *ISA.get_or_init(|| {
            let v3 = std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("fma")
                && std::arch::is_x86_feature_detected!("bmi1")
                && std::arch::is_x86_feature_detected!("bmi2")
                && std::arch::is_x86_feature_detected!("lzcnt")
                && std::arch::is_x86_feature_detected!("popcnt");
            match (v3, std::arch::is_x86_feature_detected!("avx512f")) {
                (false, _) => Isa::Portable,
                (true, false) => Isa::Avx2,
                (true, true) => Isa::Avx512,
            }
        })
    }
    #[cfg(not(target_arch = "x86_64"))]
    Isa::Portable
}

/// The instruction set the vector copies use: [`cpu_isa`], capped by the environment
/// (`HEMI_SIMD=portable`: none; `HEMI_NO_AVX512=1`: no AVX-512). Read once per process.
pub fn isa() -> Isa {
    static ISA: std::sync::OnceLock<Isa> = std::sync::OnceLock::new();
    *ISA.get_or_init(|| {
        let set = |name: &str, value: &str| std::env::var(name).is_ok_and(|v| v.trim() == value);
        let cap = if set("HEMI_SIMD", "portable") {
            Isa::Portable
        } else if set("HEMI_NO_AVX512", "1") {
            Isa::Avx2
        } else {
            Isa::Avx512
        };
        cpu_isa().min(cap)
    })
}

/// Whether the AVX-512 copies may run: [`isa`] is [`Isa::Avx512`] (which includes x86-64-v3;
/// the copies are compiled with it too).
pub(crate) fn avx512() -> bool {
    isa() >= Isa::Avx512
}

/// Rays per packet on this CPU and environment: sixteen where [`avx512()`] allows, eight
/// otherwise (what eight-wide trees trace, and the width the cosine table is laid out in).
pub(crate) fn packet_lanes() -> usize {
    if avx512() { 16 } else { 8 }
}

/// A kernel written once over the lane type `L`, which [`Lanes::compiled`] compiles for `L`'s
/// instruction set: the entry points marked `#[target_feature]` are generated there, once per
/// lane type, and `run` (`#[inline(always)]` in each implementation) is inlined into them with
/// everything it inlines in turn.
pub(crate) trait Kernel<L: Lanes> {
    /// What the kernel returns.
    type Output;
    /// Runs the kernel; `isa` proves the CPU has `L`'s instruction set.
    fn run(self, isa: L::Isa) -> Self::Output;
}

/// Runs `kernel` in `lanes` lanes, compiled for that lane type's instruction set: [`Avx512`]
/// for sixteen (where [`isa`] allows it), [`Avx`] for eight where it allows AVX2, else
/// [`Portable`]; `None`, having done nothing, for other widths.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(crate) fn run_in<K, O>(lanes: usize, kernel: K) -> Option<O>
where
    K: Kernel<Avx, Output = O> + Kernel<Avx512, Output = O> + Kernel<Portable, Output = O>,
{
    match lanes {
        16 => HasAvx512::allowed().map(|isa| Avx512::compiled(isa, kernel)),
        8 => Some(match Eight::allowed() {
            Eight::Avx(isa) => Avx::compiled(isa, kernel),
            Eight::Portable(isa) => Portable::compiled(isa, kernel),
        }),
        _ => None,
    }
}

/// Runs a test's eight-lane version where the CPU has AVX2 and its sixteen-lane version where
/// it has AVX-512 as well (whatever the environment caps [`isa`] at: the copies are tested
/// wherever they can run), saying which it skips.
#[cfg(all(test, target_arch = "x86_64"))]
pub(crate) fn both_widths(eight: impl FnOnce(HasAvx2), sixteen: impl FnOnce(HasAvx512)) {
    let Some(v3) = HasAvx2::on_cpu() else {
        eprintln!("no AVX2 on this CPU: packets are not used and not tested");
        return;
    };
    eight(v3);
    match HasAvx512::on_cpu() {
        Some(v4) => sixteen(v4),
        None => eprintln!("no AVX-512 on this CPU: sixteen-lane packets are not used and not tested"),
    }
}

/// Defines a function whose body is compiled once per instruction set, AVX-512 and AVX2 copies
/// marked `#[target_feature]` and a portable one, and which runs the copy [`isa`] allows: for
/// loops the compiler vectorises by itself. The body is an `#[inline(always)]` function, so
/// that it (and what it calls inline) is compiled into each copy with that copy's features.
macro_rules! multiversion {
    ($(#[$m:meta])* $vis:vis fn $name:ident($($arg:ident: $ty:ty),* $(,)?) $body:block) => {
        $(#[$m])*
        $vis fn $name($($arg: $ty),*) {
            #[inline(always)]
            fn body($($arg: $ty),*) $body
            #[cfg(target_arch = "x86_64")]
            #[target_feature(enable = "avx512f,avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
            fn avx512($($arg: $ty),*) {
                body($($arg),*)
            }
            #[cfg(target_arch = "x86_64")]
            #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
            fn avx2($($arg: $ty),*) {
                body($($arg),*)
            }
            match $crate::simd::isa() {
                // SAFETY: `isa` allows AVX-512 only where the CPU has it and x86-64-v3.
                #[cfg(target_arch = "x86_64")]
                $crate::simd::Isa::Avx512 => unsafe { avx512($($arg),*) },
                // SAFETY: `isa` allows AVX2 only where the CPU has x86-64-v3.
                #[cfg(target_arch = "x86_64")]
                $crate::simd::Isa::Avx2 => unsafe { avx2($($arg),*) },
                _ => body($($arg),*),
            }
        }
    };
}
pub(crate) use multiversion;
