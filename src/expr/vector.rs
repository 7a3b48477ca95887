//! sin, cos, exp, log and powers of many values at once: glibc's vector math library (libmvec,
//! four values per call with AVX2) where the processor and the C library have it, the standard
//! library's scalar functions elsewhere. They are most of the cost of evaluating the loads and the
//! exact solutions at quadrature points.
//!
//! Every value is computed the same way wherever it stands in a batch (a short tail is padded to
//! four), so that a point's value does not depend on the points evaluated with it, nor on the
//! number of threads. libmvec's functions are within 4 units in the last place of the exact value
//! (glibc's manual), the scalar ones within 1: the two differ in the last bits.

/// A function evaluated by [`apply`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Function {
    Sin,
    Cos,
    Exp,
    Log,
}

/// out[i] = f(a[i]).
pub(super) fn apply(f: Function, a: &[f64], out: &mut [f64]) {
    #[cfg(all(target_arch = "x86_64", target_os = "linux", target_env = "gnu"))]
    if libmvec::available() {
        // SAFETY: the processor has AVX2 and FMA, which the functions called need.
        unsafe { libmvec::apply(f, a, out) };
        return;
    }
    scalar(f, a, out);
}

/// Whether [`apply`] runs on libmvec here.
pub(super) fn vectorised() -> bool {
    #[cfg(all(target_arch = "x86_64", target_os = "linux", target_env = "gnu"))]
    return libmvec::available();
    #[cfg(not(all(target_arch = "x86_64", target_os = "linux", target_env = "gnu")))]
    false
}

/// out[i] = a[i]^b[i].
pub(super) fn pow(a: &[f64], b: &[f64], out: &mut [f64]) {
    #[cfg(all(target_arch = "x86_64", target_os = "linux", target_env = "gnu"))]
    if libmvec::available() {
        // SAFETY: the processor has AVX2 and FMA, which the function called needs.
        unsafe { libmvec::pow(a, b, out) };
        return;
    }
    scalar_pow(a, b, out);
}

/// out[i] = a[i]^b[i] by the standard library.
pub(super) fn scalar_pow(a: &[f64], b: &[f64], out: &mut [f64]) {
    (out.iter_mut().zip(a).zip(b)).for_each(|((o, a), b)| *o = a.powf(*b));
}

/// out[i] = f(a[i]) by the standard library.
pub(super) fn scalar(f: Function, a: &[f64], out: &mut [f64]) {
    let f = match f {
        Function::Sin => f64::sin,
        Function::Cos => f64::cos,
        Function::Exp => f64::exp,
        Function::Log => f64::ln,
    };
    out.iter_mut().zip(a).for_each(|(o, a)| *o = f(*a));
}

#[cfg(all(target_arch = "x86_64", target_os = "linux", target_env = "gnu"))]
mod libmvec {
    use super::Function;
    use std::arch::asm;
    use std::arch::x86_64::{__m256d, _mm256_loadu_pd, _mm256_storeu_pd};

    // The AVX2 variants (glibc ≥ 2.22) of the vector-function ABI of x86-64: four doubles in
    // ymm0, the results in ymm0. A declaration cannot name a SIMD type in stable Rust, so they
    // are declared without one and called by `asm!` (`four`).
    #[link(name = "mvec")]
    extern "C" {
        fn _ZGVdN4v_sin();
        fn _ZGVdN4v_cos();
        fn _ZGVdN4v_exp();
        fn _ZGVdN4v_log();
        fn _ZGVdN4vv_pow();
    }

    /// Whether the processor has what the AVX2 variants need.
    pub(super) fn available() -> bool {
        std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
    }

    /// out[i] = f(a[i]), four at a time.
    ///
    /// # Safety
    /// The processor must have AVX2 and FMA ([`available`]).
    #[target_feature(enable = "avx2,fma")]
    pub(super) unsafe fn apply(f: Function, a: &[f64], out: &mut [f64]) {
        by_fours(&[a], out, |[v]| four(f, v));
    }

    /// out[i] = a[i]^b[i], four at a time.
    ///
    /// # Safety
    /// The processor must have AVX2 and FMA ([`available`]).
    #[target_feature(enable = "avx2,fma")]
    pub(super) unsafe fn pow(a: &[f64], b: &[f64], out: &mut [f64]) {
        by_fours(&[a, b], out, |[mut x, y]| {
            // SAFETY: as in `four`, with the exponents in ymm1.
            unsafe {
                asm!("call {f}", f = sym _ZGVdN4vv_pow, inout("ymm0") x, in("ymm1") y, clobber_abi("C"))
            };
            x
        });
    }

    /// out[i] = g of the i-th values of `args`, four at a time; a short tail padded with zeros.
    #[target_feature(enable = "avx2,fma")]
    fn by_fours<const N: usize>(args: &[&[f64]; N], out: &mut [f64], g: impl Fn([__m256d; N]) -> __m256d) {
        let full = out.len() / 4 * 4;
        for at in (0..full).step_by(4) {
            // SAFETY: each slice holds four doubles.
            let v = args.map(|a| unsafe { _mm256_loadu_pd(a[at..at + 4].as_ptr()) });
            unsafe { _mm256_storeu_pd(out[at..at + 4].as_mut_ptr(), g(v)) };
        }
        let n = out.len() - full;
        if n > 0 {
            let v = args.map(|a| {
                let mut x = [0.0; 4];
                x[..n].copy_from_slice(&a[full..full + n]);
                // SAFETY: x holds four doubles.
                unsafe { _mm256_loadu_pd(x.as_ptr()) }
            });
            let mut y = [0.0; 4];
            // SAFETY: y holds four doubles.
            unsafe { _mm256_storeu_pd(y.as_mut_ptr(), g(v)) };
            out[full..].copy_from_slice(&y[..n]);
        }
    }

    /// f of the four values of v.
    #[target_feature(enable = "avx2,fma")]
    fn four(f: Function, mut v: __m256d) -> __m256d {
        macro_rules! call {
            ($name:ident) => {
                // SAFETY: the function takes and returns ymm0 and may change any register that a
                // C function may; the stack is aligned for a call on entry to `asm!`.
                unsafe { asm!("call {f}", f = sym $name, inout("ymm0") v, clobber_abi("C")) }
            };
        }
        match f {
            Function::Sin => call!(_ZGVdN4v_sin),
            Function::Cos => call!(_ZGVdN4v_cos),
            Function::Exp => call!(_ZGVdN4v_exp),
            Function::Log => call!(_ZGVdN4v_log),
        }
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Against the standard library within 4 units in the last place (also at ±0, ±∞, NaN,
    /// tiny and huge arguments; powers of negative, zero and huge bases), and each value the same
    /// wherever it stands in a batch.
    #[test]
    fn values_agree_with_the_scalar_functions() {
        let mut a: Vec<f64> = (0..4001).map(|k| (k as f64 - 2000.0) * 0.0173).collect();
        a.extend([
            0.0,
            -0.0,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            1e-310,
            1e300,
            -1e22,
            700.0,
            710.0,
        ]);
        let b: Vec<f64> = a.iter().rev().map(|b| b / 7.0).collect();
        for f in [
            Some(Function::Sin),
            Some(Function::Cos),
            Some(Function::Exp),
            Some(Function::Log),
            None,
        ] {
            let (mut fast, mut exact) = (vec![0.0; a.len()], vec![0.0; a.len()]);
            let fast_f = |a: &[f64], b: &[f64], out: &mut [f64]| match f {
                Some(f) => apply(f, a, out),
                None => pow(a, b, out),
            };
            fast_f(&a, &b, &mut fast);
            match f {
                Some(f) => scalar(f, &a, &mut exact),
                None => scalar_pow(&a, &b, &mut exact),
            }
            for (k, (v, w)) in fast.iter().zip(&exact).enumerate() {
                let ulps = (v.to_bits() as i64).wrapping_sub(w.to_bits() as i64).abs();
                let same = v.to_bits() == w.to_bits() || (v.is_nan() && w.is_nan());
                let name = f.map_or("pow".to_string(), |f| format!("{f:?}"));
                assert!(same || ulps <= 4, "{name}({}, …) = {v:e}, not {w:e}", a[k]);
            }
            // The same values one, two and three at a time.
            for n in 1..4 {
                for (k, (chunk, exponents)) in a.chunks(n).zip(b.chunks(n)).enumerate() {
                    let mut out = [0.0; 3];
                    fast_f(chunk, exponents, &mut out[..chunk.len()]);
                    for (i, v) in out[..chunk.len()].iter().enumerate() {
                        let w = fast[k * n + i];
                        assert!(v.to_bits() == w.to_bits() || (v.is_nan() && w.is_nan()));
                    }
                }
            }
        }
    }
}
