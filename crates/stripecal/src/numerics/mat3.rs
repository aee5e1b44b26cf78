//! Generic 3-vector and 3x3 algebra over [`Scalar`] (`[T; 3]`, `[[T; 3]; 3]` row-major),
//! for model code that runs on `f64` and on dual numbers alike. nalgebra covers the
//! plain-`f64` uses; this is the one dialect for the generic ones.

use nalgebra::Matrix3;

use crate::numerics::dual::Scalar;

/// A nalgebra `f64` matrix as rows of constants.
pub fn m3<T: Scalar>(r: &Matrix3<f64>) -> [[T; 3]; 3] {
    std::array::from_fn(|i| std::array::from_fn(|j| T::from_f64(r[(i, j)])))
}

/// `a b`.
pub fn matmul<T: Scalar>(a: &[[T; 3]; 3], b: &[[T; 3]; 3]) -> [[T; 3]; 3] {
    std::array::from_fn(|i| {
        std::array::from_fn(|j| a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j])
    })
}

/// `a^T`.
pub fn transpose<T: Scalar>(a: &[[T; 3]; 3]) -> [[T; 3]; 3] {
    std::array::from_fn(|i| std::array::from_fn(|j| a[j][i]))
}

/// `a v`.
pub fn matvec<T: Scalar>(a: &[[T; 3]; 3], v: &[T; 3]) -> [T; 3] {
    std::array::from_fn(|i| a[i][0] * v[0] + a[i][1] * v[1] + a[i][2] * v[2])
}

/// `a x b`.
pub fn cross<T: Scalar>(a: &[T; 3], b: &[T; 3]) -> [T; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// `a . b`.
pub fn dot<T: Scalar>(a: &[T; 3], b: &[T; 3]) -> T {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// `R0 (I + [w]x)` for a dual `w` with value 0: `R0 Exp(w)` to first order, which is
/// exact for the value and the first derivatives.
pub fn rot_times_exp_first_order<T: Scalar>(r0: &Matrix3<f64>, w: &[T; 3]) -> [[T; 3]; 3] {
    let zero = T::from_f64(0.0);
    // [w]x
    let wx = [
        [zero, -w[2], w[1]],
        [w[2], zero, -w[0]],
        [-w[1], w[0], zero],
    ];
    std::array::from_fn(|i| {
        std::array::from_fn(|j| {
            let mut s = T::from_f64(r0[(i, j)]);
            for (k, row) in wx.iter().enumerate() {
                s = s + row[j].scale(r0[(i, k)]);
            }
            s
        })
    })
}

/// The rows of a nalgebra `f64` matrix.
pub fn rows_f64(r: &Matrix3<f64>) -> [[f64; 3]; 3] {
    std::array::from_fn(|i| std::array::from_fn(|j| r[(i, j)]))
}
