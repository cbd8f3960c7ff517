//! Instruction-set tokens: zero-sized values that prove the CPU has an instruction set. Only
//! this module makes them, and only after [`super::isa`] (or, in tests, [`super::cpu_isa`])
//! found the set, so code holding one may run that set's instructions without `unsafe`: the
//! lane types' constructors take a token, and a lane value, made only from a token or from
//! other values, is a proof in turn.

#[cfg(target_arch = "x86_64")]
use super::{Isa, isa};

/// Proof that the CPU has x86-64-v3 (AVX2, FMA, BMI1/2, LZCNT, POPCNT): the eight-lane
/// vector copies ([`super::Avx`]) may run.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy, Debug)]
pub(crate) struct HasAvx2(pub(super) ());

/// Proof that the CPU has AVX-512F and x86-64-v3: the sixteen-lane copies
/// ([`super::Avx512`]) may run.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy, Debug)]
pub(crate) struct HasAvx512(pub(super) ());

/// The portable lanes' token ([`super::Portable`]): they need no instruction set, so anyone
/// may make one.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Plain;

#[cfg(target_arch = "x86_64")]
impl HasAvx2 {
    /// The token where [`isa`] allows the eight-lane copies.
    #[inline]
    pub(crate) fn allowed() -> Option<Self> {
        (isa() >= Isa::Avx2).then_some(HasAvx2(()))
    }

    /// The token where the CPU has the set, whatever the environment caps [`isa`] at: for
    /// tests, which run every copy the CPU can.
    #[cfg(test)]
    pub(crate) fn on_cpu() -> Option<Self> {
        (super::cpu_isa() >= Isa::Avx2).then_some(HasAvx2(()))
    }
}

#[cfg(target_arch = "x86_64")]
impl HasAvx512 {
    /// The token where [`isa`] allows the sixteen-lane copies.
    #[inline]
    pub(crate) fn allowed() -> Option<Self> {
        (isa() >= Isa::Avx512).then_some(HasAvx512(()))
    }

    /// [`HasAvx2::on_cpu`] for AVX-512.
    #[cfg(test)]
    pub(crate) fn on_cpu() -> Option<Self> {
        (super::cpu_isa() >= Isa::Avx512).then_some(HasAvx512(()))
    }
}

/// AVX-512 is only detected together with x86-64-v3 ([`cpu_isa`](super::cpu_isa)).
#[cfg(target_arch = "x86_64")]
impl From<HasAvx512> for HasAvx2 {
    #[inline(always)]
    fn from(_: HasAvx512) -> Self {
        HasAvx2(())
    }
}

/// The token of the eight-lane copies this process runs: AVX2's where [`isa`] allows it, else
/// the portable lanes' (the same kernels, in plain arrays).
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy, Debug)]
pub(crate) enum Eight {
    /// [`super::Avx`] lanes.
    Avx(HasAvx2),
    /// [`super::Portable`] lanes.
    Portable(Plain),
}

#[cfg(target_arch = "x86_64")]
impl Eight {
    /// The eight lanes [`isa`] allows.
    #[inline]
    pub(crate) fn allowed() -> Self {
        HasAvx2::allowed().map_or(Eight::Portable(Plain), Eight::Avx)
    }
}
