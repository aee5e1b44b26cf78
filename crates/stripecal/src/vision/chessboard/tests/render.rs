//! An exact synthetic chessboard renderer for the tests: a pinhole camera with radial
//! distortion looking at the board, the scene convolved with a Gaussian PSF and the
//! pixel box (rendered on a 4x finer grid with adaptive area sampling), times an
//! illumination field, plus an optional bright stripe, Gaussian noise, quantisation.

use nalgebra::{Matrix3, Rotation3, Vector3};

use crate::model::board::Board;

/// A rendered scene's settings.
#[derive(Debug, Clone)]
pub struct Scene {
    pub w: usize,
    pub h: usize,
    pub board: Board,
    /// Board-to-camera rotation and translation (mm); the board's pattern centre is at
    /// the board origin shifted by `centre`.
    pub rot: Matrix3<f64>,
    pub t: Vector3<f64>,
    pub f: f64,
    pub k1: f64,
    pub dark: f64,
    pub light: f64,
    pub blur: f64,
    pub noise: f64,
    /// Illumination gain at pixel `(u, v)`.
    pub gain: fn(f64, f64, usize, usize) -> f64,
    /// A stripe `(point, direction, half-width px, added brightness)`.
    pub stripe: Option<([f64; 2], [f64; 2], f64, f64)>,
    pub seed: u64,
}

pub fn flat(_: f64, _: f64, _: usize, _: usize) -> f64 {
    1.0
}

impl Scene {
    /// The board centred in the image, `width_frac` of the image width across, turned
    /// `roll` degrees in the image, tilted `tilt` degrees about an axis at `axis`
    /// degrees in the board plane.
    pub fn new(
        board: &Board,
        w: usize,
        h: usize,
        roll: f64,
        tilt: f64,
        axis: f64,
        width_frac: f64,
    ) -> Scene {
        let f = 1.2 * w as f64;
        let e = board.pattern_extent();
        let bw = e[1] - e[0];
        let z = f * bw / (width_frac * w as f64);
        let ax = Vector3::new(axis.to_radians().cos(), axis.to_radians().sin(), 0.0);
        let r_tilt =
            Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(ax), tilt.to_radians());
        let r_roll = Rotation3::from_axis_angle(&Vector3::z_axis(), roll.to_radians());
        let rot = (r_roll * r_tilt).into_inner();
        let c = Vector3::new(0.5 * (e[0] + e[1]), 0.5 * (e[2] + e[3]), 0.0);
        let t = Vector3::new(0.0, 0.0, z) - rot * c;
        Scene {
            w,
            h,
            board: board.clone(),
            rot,
            t,
            f,
            k1: 0.0,
            dark: 30.0,
            light: 200.0,
            blur: 0.7,
            noise: 1.0,
            gain: flat,
            stripe: None,
            seed: 7,
        }
    }

    fn centre(&self) -> (f64, f64) {
        (0.5 * (self.w as f64 - 1.0), 0.5 * (self.h as f64 - 1.0))
    }

    /// Image position of board point `(x, y)`.
    pub fn project(&self, x: f64, y: f64) -> [f64; 2] {
        let p = self.rot * Vector3::new(x, y, 0.0) + self.t;
        let (xn, yn) = (p.x / p.z, p.y / p.z);
        let d = 1.0 + self.k1 * (xn * xn + yn * yn);
        let (cx, cy) = self.centre();
        [cx + self.f * xn * d, cy + self.f * yn * d]
    }

    /// Board point seen at pixel `(u, v)` (`None` behind the camera).
    fn unproject(&self, u: f64, v: f64, hinv: &Matrix3<f64>) -> Option<(f64, f64)> {
        let (cx, cy) = self.centre();
        let (xd, yd) = ((u - cx) / self.f, (v - cy) / self.f);
        let (mut x, mut y) = (xd, yd);
        for _ in 0..if self.k1 == 0.0 { 0 } else { 8 } {
            let d = 1.0 + self.k1 * (x * x + y * y);
            x = xd / d;
            y = yd / d;
        }
        let q = hinv * Vector3::new(x, y, 1.0);
        (q.z.abs() > 1e-12).then(|| (q.x / q.z, q.y / q.z))
    }

    /// The true corners, row-major.
    pub fn truth(&self) -> Vec<[f64; 2]> {
        self.board
            .indices()
            .map(|(r, c)| {
                let p = self.board.center(r, c);
                self.project(p.x, p.y)
            })
            .collect()
    }

    /// The scene as floats (before noise and quantisation): the sharp scene's area
    /// means over quarter pixels (8 x 8 samples where an edge crosses one), the PSF
    /// applied on that 4x grid, then each pixel the mean of its 4 x 4 quarter pixels,
    /// so the result is the scene convolved with the PSF and the pixel box.
    pub fn render_f(&self) -> Vec<f64> {
        const S: usize = 4;
        const N: usize = 8;
        let (w, h) = (self.w, self.h);
        let (sw, sh) = (w * S, h * S);
        let hm = Matrix3::from_columns(&[
            self.rot.column(0).into_owned(),
            self.rot.column(1).into_owned(),
            self.t,
        ]);
        let hinv = hm.try_inverse().expect("invertible pose");
        let val = |u: f64, v: f64| match self.unproject(u, v, &hinv) {
            Some((x, y)) if self.board.ink_at(x, y).is_some() => self.dark,
            _ => self.light,
        };
        let sub = 1.0 / S as f64;
        // scene at the quarter-pixel corners
        let corner = |cx: usize, cy: usize| val(cx as f64 * sub - 0.5, cy as f64 * sub - 0.5);
        let mut cv = vec![0f64; (sw + 1) * (sh + 1)];
        for cy in 0..=sh {
            for cx in 0..=sw {
                cv[cy * (sw + 1) + cx] = corner(cx, cy);
            }
        }
        let mut fine = vec![0f64; sw * sh];
        for y in 0..sh {
            for x in 0..sw {
                let c = [
                    cv[y * (sw + 1) + x],
                    cv[y * (sw + 1) + x + 1],
                    cv[(y + 1) * (sw + 1) + x],
                    cv[(y + 1) * (sw + 1) + x + 1],
                ];
                let (u0, v0) = (x as f64 * sub - 0.5, y as f64 * sub - 0.5);
                let a = if c.iter().all(|&p| p == c[0]) {
                    c[0]
                } else {
                    let mut acc = 0.0;
                    for sy in 0..N {
                        for sx in 0..N {
                            acc += val(
                                u0 + (sx as f64 + 0.5) * sub / N as f64,
                                v0 + (sy as f64 + 0.5) * sub / N as f64,
                            );
                        }
                    }
                    acc / (N * N) as f64
                };
                let (u, v) = (u0 + 0.5 * sub, v0 + 0.5 * sub);
                fine[y * sw + x] = a * (self.gain)(u, v, w, h);
            }
        }
        let fine = blur(&fine, sw, sh, self.blur * S as f64);
        let mut img = vec![0f64; w * h];
        for y in 0..h {
            for x in 0..w {
                let mut acc = 0.0;
                for sy in 0..S {
                    for sx in 0..S {
                        acc += fine[(y * S + sy) * sw + x * S + sx];
                    }
                }
                img[y * w + x] = acc / (S * S) as f64;
            }
        }
        if let Some((p, d, hw, amp)) = self.stripe {
            let n = (d[0] * d[0] + d[1] * d[1]).sqrt();
            for y in 0..h {
                for x in 0..w {
                    let dist = ((x as f64 - p[0]) * d[1] - (y as f64 - p[1]) * d[0]).abs() / n;
                    img[y * w + x] += amp * (-(dist / hw).powi(4)).exp();
                }
            }
        }
        img
    }

    /// The 8-bit image.
    pub fn render(&self) -> Vec<u8> {
        let f = self.render_f();
        let mut rng = Rng(self.seed);
        f.iter()
            .map(|&v| (v + self.noise * rng.normal()).round().clamp(0.0, 255.0) as u8)
            .collect()
    }

    /// The 16-bit image (the 8-bit scale times 257).
    pub fn render16(&self) -> Vec<u16> {
        let f = self.render_f();
        let mut rng = Rng(self.seed);
        f.iter()
            .map(|&v| {
                ((v + self.noise * rng.normal()) * 257.0)
                    .round()
                    .clamp(0.0, 65535.0) as u16
            })
            .collect()
    }
}

/// Separable Gaussian blur (radius 4 sigma, edges clamped).
pub fn blur(img: &[f64], w: usize, h: usize, s: f64) -> Vec<f64> {
    if s <= 0.0 {
        return img.to_vec();
    }
    let r = (4.0 * s).ceil() as i64;
    let k: Vec<f64> = (-r..=r)
        .map(|d| (-(d * d) as f64 / (2.0 * s * s)).exp())
        .collect();
    let ks: f64 = k.iter().sum();
    let k: Vec<f64> = k.iter().map(|v| v / ks).collect();
    let mut tmp = vec![0f64; w * h];
    for y in 0..h {
        for x in 0..w {
            let mut acc = 0.0;
            for (o, kv) in k.iter().enumerate() {
                let xx = (x as i64 + o as i64 - r).clamp(0, w as i64 - 1) as usize;
                acc += kv * img[y * w + xx];
            }
            tmp[y * w + x] = acc;
        }
    }
    let mut out = vec![0f64; w * h];
    for y in 0..h {
        for x in 0..w {
            let mut acc = 0.0;
            for (o, kv) in k.iter().enumerate() {
                let yy = (y as i64 + o as i64 - r).clamp(0, h as i64 - 1) as usize;
                acc += kv * tmp[yy * w + x];
            }
            out[y * w + x] = acc;
        }
    }
    out
}

/// A small deterministic generator.
pub struct Rng(pub u64);

impl Rng {
    pub fn uniform(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }

    pub fn normal(&mut self) -> f64 {
        let (a, b) = (self.uniform(), self.uniform());
        (-2.0 * a.ln()).sqrt() * (2.0 * std::f64::consts::PI * b).cos()
    }
}
