//! Forward-mode dual numbers ([`Dual`]) and the [`Scalar`] arithmetic that generic model
//! code is written over (`f64` for values, `Dual<N>` for values with `N` exact
//! directional derivatives).
//!
//! A dual number `v + sum_i d_i eps_i` (`eps_i eps_j = 0`) carries the value and the
//! gradient along the `N` chosen directions; every operation applies the chain rule, so
//! a function written once over [`Scalar`] gives its Jacobian exactly to round-off.

use std::ops::{Add, Div, Mul, Neg, Sub};

/// A number with `N` directional derivatives (forward-mode automatic differentiation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Dual<const N: usize> {
    pub v: f64,
    pub d: [f64; N],
}

impl<const N: usize> Dual<N> {
    /// A constant.
    pub fn cst(v: f64) -> Self {
        Dual { v, d: [0.0; N] }
    }
    /// The `i`-th variable with value `v`.
    pub fn var(v: f64, i: usize) -> Self {
        let mut d = [0.0; N];
        if i < N {
            d[i] = 1.0;
        }
        Dual { v, d }
    }
}

/// The arithmetic generic model code needs (implemented by `f64` and [`Dual`]).
pub trait Scalar:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
{
    fn from_f64(x: f64) -> Self;
    fn value(self) -> f64;
    fn sqrt(self) -> Self;
    fn scale(self, k: f64) -> Self;
    /// Zero with zero derivatives (a coefficient that plays no part).
    fn is_zero(&self) -> bool;
}

impl Scalar for f64 {
    #[inline]
    fn from_f64(x: f64) -> Self {
        x
    }
    #[inline]
    fn value(self) -> f64 {
        self
    }
    #[inline]
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }
    #[inline]
    fn scale(self, k: f64) -> Self {
        self * k
    }
    #[inline]
    fn is_zero(&self) -> bool {
        *self == 0.0
    }
}

impl<const N: usize> Add for Dual<N> {
    type Output = Self;
    #[inline]
    fn add(mut self, o: Self) -> Self {
        self.v += o.v;
        for i in 0..N {
            self.d[i] += o.d[i];
        }
        self
    }
}
impl<const N: usize> Sub for Dual<N> {
    type Output = Self;
    #[inline]
    fn sub(mut self, o: Self) -> Self {
        self.v -= o.v;
        for i in 0..N {
            self.d[i] -= o.d[i];
        }
        self
    }
}
impl<const N: usize> Mul for Dual<N> {
    type Output = Self;
    #[inline]
    fn mul(self, o: Self) -> Self {
        let mut d = [0.0; N];
        for (i, di) in d.iter_mut().enumerate() {
            *di = self.d[i] * o.v + self.v * o.d[i];
        }
        Dual { v: self.v * o.v, d }
    }
}
impl<const N: usize> Div for Dual<N> {
    type Output = Self;
    #[inline]
    fn div(self, o: Self) -> Self {
        let inv = 1.0 / o.v;
        let q = self.v * inv;
        let mut d = [0.0; N];
        for (i, di) in d.iter_mut().enumerate() {
            *di = (self.d[i] - q * o.d[i]) * inv;
        }
        Dual { v: q, d }
    }
}
impl<const N: usize> Neg for Dual<N> {
    type Output = Self;
    #[inline]
    fn neg(mut self) -> Self {
        self.v = -self.v;
        for x in self.d.iter_mut() {
            *x = -*x;
        }
        self
    }
}
impl<const N: usize> Scalar for Dual<N> {
    #[inline]
    fn from_f64(x: f64) -> Self {
        Dual::cst(x)
    }
    #[inline]
    fn is_zero(&self) -> bool {
        self.v == 0.0 && self.d.iter().all(|x| *x == 0.0)
    }
    #[inline]
    fn value(self) -> f64 {
        self.v
    }
    #[inline]
    fn sqrt(self) -> Self {
        let s = self.v.sqrt();
        let k = 0.5 / s;
        let mut d = self.d;
        for x in d.iter_mut() {
            *x *= k;
        }
        Dual { v: s, d }
    }
    #[inline]
    fn scale(mut self, k: f64) -> Self {
        self.v *= k;
        for x in self.d.iter_mut() {
            *x *= k;
        }
        self
    }
}
