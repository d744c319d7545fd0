//! Run-time choice of instruction set for the hot loops: each is written once as plain
//! Rust over fixed-size chunks that the compiler vectorises, and compiled twice, for the
//! baseline target and, on x86-64, for AVX2 (twice the vector width), the copy used when
//! the CPU has it.

/// Defines a function whose body is compiled twice: as it is, and on x86-64 once more
/// with AVX2 enabled; a call runs the AVX2 copy when the CPU supports AVX2 (detected
/// once, then a cached check). The body should call an `#[inline(always)]` function, so
/// that the whole loop is compiled into each copy. Parameters are plain names; const
/// generic parameters are allowed.
macro_rules! avx2_multiversion {
    (
        $(#[$attr:meta])*
        $vis:vis fn $name:ident $(<$(const $cg:ident: $cty:ty),+ $(,)?>)?
            ($($arg:ident: $ty:ty),* $(,)?) $(-> $ret:ty)? $body:block
    ) => {
        $(#[$attr])*
        $vis fn $name $(<$(const $cg: $cty),+>)? ($($arg: $ty),*) $(-> $ret)? {
            #[inline(always)]
            fn portable $(<$(const $cg: $cty),+>)? ($($arg: $ty),*) $(-> $ret)? $body

            #[cfg(target_arch = "x86_64")]
            #[target_feature(enable = "avx2")]
            unsafe fn avx2 $(<$(const $cg: $cty),+>)? ($($arg: $ty),*) $(-> $ret)? {
                portable $(::<$($cg),+>)? ($($arg),*)
            }

            #[cfg(target_arch = "x86_64")]
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the CPU supports AVX2, the only feature `avx2` is compiled for.
                return unsafe { avx2 $(::<$($cg),+>)? ($($arg),*) };
            }
            portable $(::<$($cg),+>)? ($($arg),*)
        }
    };
}

pub(crate) use avx2_multiversion;
