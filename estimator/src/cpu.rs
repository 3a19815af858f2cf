//! What this CPU runs, detected in one place (feature matching picks its kernel from these
//! checks too), and hot loops compiled more than once: for the x86_64 baseline, for AVX2
//! and for AVX-512, and run with the best this machine has (the simulator's loops use it
//! too). The arithmetic is the same in every version: wider registers do the same IEEE
//! operations lane by lane, and Rust never fuses a multiply and an add, so every version
//! gives the same bits.

// Enabling a feature for the compiler enables the ones it implies too, which CPUID reports
// separately: AVX2 implies AVX, AVX-512 F implies AVX2, FMA and F16C, and AVX-512 BW and
// VNNI imply F. Each check below covers those as well, so it vouches for everything the
// code it guards is compiled with.

/// Whether this machine runs AVX2 (and AVX).
pub fn avx2_available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("avx")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Whether this machine runs the AVX-512 subsets the wide loops use: F, BW, DQ and VL
/// (and with them AVX2, FMA and F16C).
pub fn avx512_available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        avx512f_available()
            && std::arch::is_x86_feature_detected!("avx512bw")
            && std::arch::is_x86_feature_detected!("avx512dq")
            && std::arch::is_x86_feature_detected!("avx512vl")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Whether this machine runs AVX-512 F and what it implies: AVX2, FMA and F16C (feature
/// matching's AVX-512 kernel).
fn avx512f_available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx512f")
            && avx2_available()
            && std::arch::is_x86_feature_detected!("fma")
            && std::arch::is_x86_feature_detected!("f16c")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Whether this machine runs AVX-512 F and BW with VNNI (feature matching's byte kernel).
fn avx512_vnni_available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        avx512f_available()
            && std::arch::is_x86_feature_detected!("avx512bw")
            && std::arch::is_x86_feature_detected!("avx512vnni")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Declares a proof that this machine runs a set of instructions: a type with a private
/// field whose one constructor is run-time detection, so holding a value is the check.
/// Code that runs functions compiled with `#[target_feature]` takes the matching proof
/// instead of trusting its caller.
macro_rules! cpu_proof {
    ($(#[$meta:meta])* $name:ident, $available:path) => {
        $(#[$meta])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq)]
        // Elsewhere only the scalar code runs and no proof is asked for.
        #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
        pub struct $name(());

        impl $name {
            /// The proof, when this machine has the instructions.
            pub fn detect() -> Option<$name> {
                $available().then_some($name(()))
            }
        }
    };
}

cpu_proof!(
    /// This machine runs AVX2.
    Avx2,
    avx2_available
);
cpu_proof!(
    /// This machine runs AVX-512 F (and AVX2, FMA and F16C).
    Avx512F,
    avx512f_available
);
cpu_proof!(
    /// This machine runs AVX-512 F, BW, DQ and VL (and AVX2, FMA and F16C).
    Avx512,
    avx512_available
);
cpu_proof!(
    /// This machine runs AVX-512 F, BW and VNNI (and AVX2, FMA and F16C).
    Avx512Vnni,
    avx512_vnni_available
);

/// Defines `fn $name(args)` that calls the `#[inline(always)]` function `$body(args)`
/// inlined into a copy compiled with AVX-512 (F, BW, DQ, VL) and AVX2, a copy with AVX2,
/// or the baseline, whichever this machine runs best. The copies are local to the function
/// and only called after the check that vouches for their features.
#[macro_export]
#[doc(hidden)]
macro_rules! multiversion {
    ($(#[$meta:meta])* $vis:vis fn $name:ident($($arg:ident: $ty:ty),* $(,)?) => $body:path) => {
        $(#[$meta])*
        $vis fn $name($($arg: $ty),*) {
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx2,avx512f,avx512bw,avx512dq,avx512vl")]
                fn wide($($arg: $ty),*) {
                    $body($($arg),*)
                }
                #[target_feature(enable = "avx2")]
                fn narrow($($arg: $ty),*) {
                    $body($($arg),*)
                }
                if $crate::avx512_available() {
                    // SAFETY: `wide` needs AVX-512 F, BW, DQ and VL and AVX2 (and what they
                    // imply), which `avx512_available` just detected.
                    return unsafe { wide($($arg),*) };
                }
                if $crate::avx2_available() {
                    // SAFETY: `narrow` needs AVX2 (and AVX), which `avx2_available` just
                    // detected.
                    return unsafe { narrow($($arg),*) };
                }
            }
            $body($($arg),*)
        }
    };
}
