//! The hot per-point loops, compiled for the widest vector unit the CPU
//! has.
//!
//! The loops over surface points are written as plain scalar code that the
//! compiler vectorises. Built for the baseline x86-64 they run two `f64`
//! lanes wide (SSE2); [`widest`] runs them in a copy compiled with AVX2
//! (four lanes) where the CPU has it, chosen when the program runs, so
//! that one binary serves every machine. The results are bit for bit those
//! of the baseline build: Rust never fuses a multiply and an add on its
//! own, and the loops' lanes are independent points, so only how many are
//! computed at once changes.

/// A piece of work whose loops should run on the widest vector unit.
/// `run` and everything it calls in its loops must be
/// `#[inline(always)]`: only what is inlined into the wide copy is
/// compiled for it (a closure would not be, which is why this is a
/// trait). The same holds inside a kernel: a closure given to
/// `Iterator::map`, `Option::and_then` or `array::map` there stays a
/// call per element (in the evidence of many samples such calls took a
/// third of its time), so kernels use plain loops and `#[inline(always)]`
/// functions; loops over points that the compiler leaves scalar (many
/// inputs per point) are written a few points at a time, lane by lane.
pub trait Kernel {
    /// What the work returns.
    type Output;
    /// Does the work.
    fn run(self) -> Self::Output;
}

/// `[f64; L]` from a function of the lane: written out as a loop, not
/// `array::from_fn` (a closure is not inlined into the wide copy).
macro_rules! lanes {
    ($l:ident, $L:expr, $e:expr) => {{
        let mut out = [0.0; $L];
        for $l in 0..$L {
            out[$l] = $e;
        }
        out
    }};
}
pub(crate) use lanes;

/// Runs `kernel` in code compiled for the widest vector instructions this
/// CPU has.
pub fn widest<K: Kernel>(kernel: K) -> K::Output {
    /// The kernel as the operation that pulp dispatches on the CPU's
    /// features.
    struct Op<K>(K);
    impl<K: Kernel> pulp::WithSimd for Op<K> {
        type Output = K::Output;
        #[inline(always)]
        fn with_simd<S: pulp::Simd>(self, _simd: S) -> K::Output {
            self.0.run()
        }
    }
    pulp::Arch::new().dispatch(Op(kernel))
}

/// The vector unit [`widest`] runs on, in words (for benchmark reports):
/// timings taken on one do not compare with the other's.
#[must_use]
pub fn vector_unit() -> &'static str {
    /// Names the instruction set pulp picked.
    struct Probe;
    impl pulp::WithSimd for Probe {
        type Output = &'static str;
        #[inline(always)]
        fn with_simd<S: pulp::Simd>(self, _simd: S) -> &'static str {
            let name = std::any::type_name::<S>();
            if name.ends_with("V4") {
                "AVX-512"
            } else if name.ends_with("V3") {
                "AVX2"
            } else {
                "the baseline vector unit (SSE2 on x86-64)"
            }
        }
    }
    pulp::Arch::new().dispatch(Probe)
}

#[cfg(test)]
mod tests {
    use super::{Kernel, widest};

    struct Polynomial<'a>(&'a [f64]);
    impl Kernel for Polynomial<'_> {
        type Output = Vec<f64>;
        #[inline(always)]
        fn run(self) -> Vec<f64> {
            self.0.iter().map(|v| v * v - 3.0 * v + 0.5).collect()
        }
    }

    #[test]
    fn the_wide_copy_computes_what_the_scalar_code_does() {
        let x: Vec<f64> = (0..1000).map(|i| f64::from(i) * 0.37 - 11.0).collect();
        let scalar: Vec<f64> = x.iter().map(|v| v * v - 3.0 * v + 0.5).collect();
        let wide = widest(Polynomial(&x));
        assert_eq!(
            scalar.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
            wide.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
        );
    }

    /// The unit named is the one the CPU has (pulp's AVX2 level is
    /// x86-64-v3: AVX2 with FMA, BMI1/2, F16C, LZCNT and MOVBE), so that a
    /// benchmark's figures say what ran them.
    #[test]
    fn the_vector_unit_named_is_the_cpus() {
        let unit = super::vector_unit();
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::is_x86_feature_detected as has;
            let v3 = has!("avx2")
                && has!("fma")
                && has!("bmi1")
                && has!("bmi2")
                && has!("f16c")
                && has!("lzcnt")
                && has!("movbe");
            assert_eq!(unit == "AVX2" || unit == "AVX-512", v3, "{unit}");
        }
        assert!(!unit.is_empty());
    }
}
