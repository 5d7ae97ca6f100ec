//! Loops compiled for the processor's wider vectors where it has them.
//!
//! The library is built for the baseline x86-64 (two doubles per SSE2
//! instruction) so that one binary runs everywhere; a hot loop whose
//! lanes are independent (a row per lane) is compiled a second time with
//! AVX (four doubles per instruction, `#[target_feature(enable = "avx")]`
//! on a wrapper of an `#[inline(always)]` body) and that copy runs when
//! [`avx`] says the processor has it. Vectorising such a loop reorders no
//! sum and fuses no multiply-add (AVX alone has no FMA), so the bits are
//! the baseline build's.

/// Whether the processor has AVX (the check is cached by `std`).
#[inline(always)]
pub fn avx() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}
