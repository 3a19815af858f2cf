//! What this CPU runs, detected in one place (feature matching picks its kernel from these
//! checks too), and hot loops compiled more than once: for the x86_64 baseline, for AVX2
//! and for AVX-512, and run with the best this machine has (the simulator's loops use it
//! too). The arithmetic is the same in every version: wider registers do the same IEEE
//! operations lane by lane, and Rust never fuses a multiply and an add, so every version
//! gives the same bits.

/// Whether this machine runs AVX2.
pub fn avx2_available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Whether this machine runs the AVX-512 subsets the wide loops use: F, BW, DQ and VL
/// (and with them AVX2).
pub fn avx512_available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx512f")
            && std::arch::is_x86_feature_detected!("avx512bw")
            && std::arch::is_x86_feature_detected!("avx512dq")
            && std::arch::is_x86_feature_detected!("avx512vl")
            && std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Whether this machine runs AVX2 with FMA (feature matching's AVX2 kernel).
pub fn avx2_fma_available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Whether this machine runs AVX-512 F (feature matching's AVX-512 kernel).
pub fn avx512f_available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx512f")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Whether this machine runs AVX-512 F and BW with VNNI (feature matching's byte kernel).
pub fn avx512_vnni_available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx512f")
            && std::arch::is_x86_feature_detected!("avx512bw")
            && std::arch::is_x86_feature_detected!("avx512vnni")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Defines `fn $name(args)` that calls the `#[inline(always)]` function `$body(args)`
/// inlined into a copy compiled with AVX-512 (F, BW, DQ, VL) and AVX2, a copy with AVX2,
/// or the baseline, whichever this machine runs best.
#[macro_export]
macro_rules! multiversion {
    ($(#[$meta:meta])* $vis:vis fn $name:ident($($arg:ident: $ty:ty),* $(,)?) => $body:path) => {
        $(#[$meta])*
        $vis fn $name($($arg: $ty),*) {
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx2,avx512f,avx512bw,avx512dq,avx512vl")]
                unsafe fn wide($($arg: $ty),*) {
                    $body($($arg),*)
                }
                #[target_feature(enable = "avx2")]
                unsafe fn narrow($($arg: $ty),*) {
                    $body($($arg),*)
                }
                if $crate::avx512_available() {
                    // SAFETY: AVX-512 F, BW, DQ and VL and AVX2 were detected.
                    return unsafe { wide($($arg),*) };
                }
                if $crate::avx2_available() {
                    // SAFETY: AVX2 was detected.
                    return unsafe { narrow($($arg),*) };
                }
            }
            $body($($arg),*)
        }
    };
}
