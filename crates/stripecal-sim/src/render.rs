//! Ray casting through the true camera model, with supersampling.
//!
//! Every pixel is integrated over its square footprint. The scene first classifies the
//! footprint from its central ray (conservatively, with an upper bound of the pixel's
//! angular radius):
//! - one material of constant reflectance and no laser light: the integrand is
//!   constant, so the central sample IS the exact supersampled value;
//! - a reflectance edge, the plate's outline or a silhouette may cross it: `(4 ss)^2`
//!   samples ([`FinePattern`]): a regular sub-pixel grid for circle grids, a
//!   multi-jittered pattern for chessboards, and `(8 ss)^2` of it where a chessboard's
//!   square corners meet (a junction inside the footprint);
//! - otherwise (the smooth laser sheet nearby): `ss x ss` samples (`ss >= 4`), promoted
//!   to the fine grid if those samples see different materials.
//!
//! Whole tiles of [`TILE`] x [`TILE`] pixels are classified first, from the tile's mean
//! ray with an angular radius that holds every footprint of the tile: a uniform tile is
//! filled with its one value (most of an image: the plate's squares, the table, the
//! background) without a ray per pixel; any other tile is rendered pixel by pixel.
//!
//! Rays come from exact undistortion: the pixel centre by Newton's method, each sub-sample by a first-order step from the centre followed by
//! one Newton correction (error far below 1e-9 px). The per-camera ray table is
//! built once and shared by all images of a dataset.

use nalgebra::{Matrix2, Vector3};
use rayon::prelude::*;

use stripecal::{BoardKind, Camera};

use crate::scene::{Footprint, ImageScene};
use crate::SimError;

/// Linear radiance of one image, per pixel, before illumination levels, PSF and noise.
#[derive(Debug, Clone)]
pub struct LinearImage {
    pub width: usize,
    pub height: usize,
    /// Mean reflectance over the pixel footprint (ambient light is applied later).
    pub ambient: Vec<f32>,
    /// Mean laser radiance over the pixel footprint.
    pub laser: Vec<f32>,
}

/// Where the `(4 ss)^2` samples of an edge pixel lie.
///
/// A regular `m x m` grid (`m = 4 ss`) measures the area of a pixel cut by a straight
/// edge that runs along a pixel row or column only to `1 / m` (every sample row sits
/// at the same `m` offsets): a systematic error of up to `1 / (2 m)` of the contrast
/// all along such an edge, i.e. a shifted edge. Circles sweep every direction, so it
/// averages out of their centroids; a chessboard's straight sides at small roll are its
/// worst case. A multi-jittered pattern (Chiu, Shirley and Wang 1994: one sample per
/// cell of the `m x m` grid AND one per row and column of the finer `m^2 x m^2` grid,
/// jittered) measures a row- or column-aligned edge to `1 / m^2` and has no lattice
/// directions along which samples line up.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FinePattern {
    /// The regular grid (circle grids: keeps their images as they always were).
    Grid,
    /// A fixed multi-jittered pattern (chessboards).
    MultiJittered,
}

impl FinePattern {
    /// The pattern for a board kind.
    pub fn for_kind(kind: BoardKind) -> FinePattern {
        match kind {
            BoardKind::Chessboard => FinePattern::MultiJittered,
            BoardKind::Circles | BoardKind::AsymmetricCircles => FinePattern::Grid,
        }
    }

    /// The `m x m` sample offsets in pixels from the pixel centre (in `(-0.5, 0.5)`),
    /// in summation order.
    pub fn offsets(self, m: usize) -> Vec<(f64, f64)> {
        match self {
            FinePattern::Grid => {
                let offs: Vec<f64> = (0..m).map(|i| (i as f64 + 0.5) / m as f64 - 0.5).collect();
                offs.iter()
                    .flat_map(|&dv| offs.iter().map(move |&du| (du, dv)))
                    .collect()
            }
            FinePattern::MultiJittered => {
                // Cell (i, j) (column i, row j) holds x in column slot i * m + sx[i][j]
                // and y in row slot j * m + sy[j][i]; shuffling sx down each column and
                // sy along each row keeps both n-rooks properties.
                let mut rng = crate::rng::Rng::new(0x6d6a, m as u64);
                let identity: Vec<usize> = (0..m).collect();
                let mut sx = vec![identity.clone(); m];
                let mut sy = vec![identity; m];
                for line in sx.iter_mut().chain(sy.iter_mut()) {
                    for a in 0..m {
                        let k = a + ((rng.uniform() * (m - a) as f64) as usize).min(m - a - 1);
                        line.swap(a, k);
                    }
                }
                let f = (m * m) as f64;
                let mut out = Vec::with_capacity(m * m);
                for j in 0..m {
                    for i in 0..m {
                        let x = ((i * m + sx[i][j]) as f64 + rng.uniform()) / f;
                        let y = ((j * m + sy[j][i]) as f64 + rng.uniform()) / f;
                        out.push((x - 0.5, y - 0.5));
                    }
                }
                out
            }
        }
    }
}

/// A camera's ray table.
pub struct Renderer {
    camera: Camera,
    ss: usize,
    /// Undistorted normalised coordinates of each pixel centre.
    centers: Vec<[f64; 2]>,
    /// Inverse distortion Jacobian at each pixel centre (row-major 2x2).
    jinv: Vec<[f32; 4]>,
    /// Sub-sample offsets from the centre in normalised coordinates, ss*ss per pixel.
    deltas: Vec<[f32; 2]>,
    /// Angular radius (radians, an upper bound) of each pixel's footprint.
    alpha: Vec<f64>,
    /// Per tile, row-major: the mean ray `(x, y, 1)` of its pixel centres and the
    /// angular radius (radians, an upper bound) of the union of its pixels' footprints.
    tiles: Vec<([f64; 2], f64)>,
}

/// Side of the square tiles classified as a whole, px.
pub const TILE: usize = 8;

impl Renderer {
    /// Builds the ray table for `camera` with `ss x ss` samples per pixel.
    pub fn new(camera: &Camera, ss: usize) -> Result<Renderer, SimError> {
        let (w, h) = (camera.width as usize, camera.height as usize);
        let n = ss * ss;
        let offs: Vec<f64> = (0..ss)
            .map(|i| (i as f64 + 0.5) / ss as f64 - 0.5)
            .collect();
        type RowTable = (Vec<[f64; 2]>, Vec<[f32; 4]>, Vec<[f32; 2]>);
        let rows: Vec<Result<RowTable, SimError>> = (0..h)
            .into_par_iter()
            .map(|row| {
                let mut c = Vec::with_capacity(w);
                let mut ji = Vec::with_capacity(w);
                let mut d = Vec::with_capacity(w * n);
                let (mut gx, mut gy) = camera.from_pixel(&nalgebra::Vector2::new(0.0, row as f64));
                for col in 0..w {
                    let (xd, yd) =
                        camera.from_pixel(&nalgebra::Vector2::new(col as f64, row as f64));
                    let (xn, yn) = camera.undistort_from(xd, yd, gx, gy).map_err(|e| {
                        SimError::Render(format!("pixel ({col}, {row}) cannot be unprojected: {e}"))
                    })?;
                    (gx, gy) = (xn, yn);
                    let (_, j) = camera.distort_with_jacobian(xn, yn);
                    let jinv = j.try_inverse().unwrap_or_else(Matrix2::identity);
                    c.push([xn, yn]);
                    ji.push([
                        jinv[(0, 0)] as f32,
                        jinv[(0, 1)] as f32,
                        jinv[(1, 0)] as f32,
                        jinv[(1, 1)] as f32,
                    ]);
                    let centre = PixelCentre {
                        xd,
                        yd,
                        xn,
                        yn,
                        jinv,
                    };
                    for &dv in &offs {
                        for &du in &offs {
                            let (sx, sy) = sub_ray(camera, &centre, du, dv);
                            d.push([(sx - xn) as f32, (sy - yn) as f32]);
                        }
                    }
                }
                Ok((c, ji, d))
            })
            .collect();
        let mut centers = Vec::with_capacity(w * h);
        let mut jinv = Vec::with_capacity(w * h);
        let mut deltas = Vec::with_capacity(w * h * n);
        for r in rows {
            let (c, ji, d) = r?;
            centers.extend(c);
            jinv.extend(ji);
            deltas.extend(d);
        }
        // Angular radius of a pixel: the farthest corner's offset in normalised
        // coordinates (first order, x1.25 for the neglected curvature).
        let alpha: Vec<f64> = jinv
            .iter()
            .map(|j| {
                let m = Matrix2::new(j[0] as f64, j[1] as f64, j[2] as f64, j[3] as f64);
                [(0.5, 0.5), (0.5, -0.5)]
                    .iter()
                    .map(|&(du, dv)| {
                        (m * nalgebra::Vector2::new(du / camera.fu, dv / camera.fv)).norm()
                    })
                    .fold(0.0, f64::max)
                    * 1.25
            })
            .collect();
        let tiles = tile_table(w, h, &centers, &alpha);
        Ok(Renderer {
            camera: camera.clone(),
            ss,
            centers,
            jinv,
            deltas,
            alpha,
            tiles,
        })
    }

    /// The camera this table was built for.
    pub fn camera(&self) -> &Camera {
        &self.camera
    }

    /// Renders the linear radiance of a scene.
    pub fn render(&self, scene: &ImageScene) -> LinearImage {
        let (w, h) = (self.camera.width as usize, self.camera.height as usize);
        let mut ambient = vec![0f32; w * h];
        let mut laser = vec![0f32; w * h];
        let fine = 4 * self.ss;
        let pattern = FinePattern::for_kind(scene.board().kind);
        let fine_offs = pattern.offsets(fine);
        // Chessboard junctions (Footprint::Corner): twice as fine again per side.
        let corner_offs = pattern.offsets(2 * fine);
        let offs = [&fine_offs[..], &corner_offs[..]];
        let tiles_x = w.div_ceil(TILE);
        ambient
            .par_chunks_mut(w * TILE)
            .zip(laser.par_chunks_mut(w * TILE))
            .enumerate()
            .for_each(|(band, (aband, lband))| {
                let rows = aband.len() / w;
                for tx in 0..tiles_x {
                    let (c0, c1) = (tx * TILE, ((tx + 1) * TILE).min(w));
                    let ([xt, yt], alpha) = self.tiles[band * tiles_x + tx];
                    if let Footprint::Uniform(hit) =
                        scene.classify(&Vector3::new(xt, yt, 1.0), alpha)
                    {
                        // every footprint of the tile sees this one material (the
                        // laser buffer is already zero)
                        for r in 0..rows {
                            aband[r * w + c0..r * w + c1].fill(hit.reflectance as f32);
                        }
                        continue;
                    }
                    for r in 0..rows {
                        for col in c0..c1 {
                            let (a, l) = self.pixel(scene, band * TILE + r, col, offs);
                            aband[r * w + col] = a;
                            lband[r * w + col] = l;
                        }
                    }
                }
            });
        LinearImage {
            width: w,
            height: h,
            ambient,
            laser,
        }
    }

    /// The mean reflectance and laser radiance over the footprint of one pixel;
    /// `offs`: the fine sample patterns of edge and corner footprints.
    fn pixel(
        &self,
        scene: &ImageScene,
        row: usize,
        col: usize,
        offs: [&[(f64, f64)]; 2],
    ) -> (f32, f32) {
        let w = self.camera.width as usize;
        let n = self.ss * self.ss;
        let idx = row * w + col;
        let [xc, yc] = self.centers[idx];
        let class = scene.classify(&Vector3::new(xc, yc, 1.0), self.alpha[idx]);
        if let Footprint::Uniform(hit) = class {
            return (hit.reflectance as f32, 0.0);
        }
        let mut sum_a = 0.0;
        let mut sum_l = 0.0;
        let mut mixed = matches!(class, Footprint::Edge | Footprint::Corner);
        if !mixed {
            let mut first = u32::MAX;
            for d in &self.deltas[idx * n..(idx + 1) * n] {
                let dir = Vector3::new(xc + d[0] as f64, yc + d[1] as f64, 1.0);
                let hit = scene.shade(&dir);
                if first == u32::MAX {
                    first = hit.material;
                } else if hit.material != first {
                    mixed = true;
                }
                sum_a += hit.reflectance;
                sum_l += hit.laser;
            }
        }
        if !mixed {
            return ((sum_a / n as f64) as f32, (sum_l / n as f64) as f32);
        }
        // Re-integrate edge pixels finely (rays computed on the fly).
        let j = self.jinv[idx];
        let jinv = Matrix2::new(j[0] as f64, j[1] as f64, j[2] as f64, j[3] as f64);
        let (xd, yd) = self
            .camera
            .from_pixel(&nalgebra::Vector2::new(col as f64, row as f64));
        let offs = if class == Footprint::Corner {
            offs[1]
        } else {
            offs[0]
        };
        let centre = PixelCentre {
            xd,
            yd,
            xn: xc,
            yn: yc,
            jinv,
        };
        let (mut sum_a, mut sum_l) = (0.0, 0.0);
        for &(du, dv) in offs {
            let (sx, sy) = sub_ray(&self.camera, &centre, du, dv);
            let hit = scene.shade(&Vector3::new(sx, sy, 1.0));
            sum_a += hit.reflectance;
            sum_l += hit.laser;
        }
        let m = offs.len() as f64;
        ((sum_a / m) as f32, (sum_l / m) as f32)
    }
}

/// The tiles of [`Renderer::tiles`]: per tile the mean of its pixels' centre rays and
/// the largest angle from it to a pixel's centre ray plus that pixel's footprint radius
/// (the triangle inequality of angles: every ray of every footprint of the tile lies
/// within it).
fn tile_table(w: usize, h: usize, centers: &[[f64; 2]], alpha: &[f64]) -> Vec<([f64; 2], f64)> {
    let ray = |c: [f64; 2]| Vector3::new(c[0], c[1], 1.0);
    let mut out = Vec::with_capacity(w.div_ceil(TILE) * h.div_ceil(TILE));
    for r0 in (0..h).step_by(TILE) {
        for c0 in (0..w).step_by(TILE) {
            let pixels = || {
                (r0..(r0 + TILE).min(h))
                    .flat_map(move |r| (c0..(c0 + TILE).min(w)).map(move |c| r * w + c))
            };
            let (mut sx, mut sy, mut k) = (0.0, 0.0, 0.0);
            for i in pixels() {
                sx += centers[i][0];
                sy += centers[i][1];
                k += 1.0;
            }
            let mid = [sx / k, sy / k];
            let m = ray(mid);
            let radius = pixels()
                .map(|i| {
                    let p = ray(centers[i]);
                    // the angle from |a x b| and a . b: accurate for small angles
                    m.cross(&p).norm().atan2(m.dot(&p)) + alpha[i]
                })
                .fold(0.0, f64::max);
            // a margin for the rounding of the angles
            out.push((mid, radius * (1.0 + 1e-9) + 1e-12));
        }
    }
    out
}

/// A pixel centre: its distorted / undistorted normalised coordinates `(xd, yd)` /
/// `(xn, yn)` and the inverse of the distortion's Jacobian at `(xn, yn)`.
#[derive(Clone, Copy)]
struct PixelCentre {
    xd: f64,
    yd: f64,
    xn: f64,
    yn: f64,
    jinv: Matrix2<f64>,
}

/// Undistorted normalised coordinates of the sub-pixel position `(du, dv)` px from a
/// pixel centre `c`.
#[inline]
fn sub_ray(cam: &Camera, c: &PixelCentre, du: f64, dv: f64) -> (f64, f64) {
    let PixelCentre {
        xd,
        yd,
        xn,
        yn,
        jinv,
    } = *c;
    let tx = xd + du / cam.fu;
    let ty = yd + dv / cam.fv;
    let (dx, dy) = (tx - xd, ty - yd);
    let mut x = xn + jinv[(0, 0)] * dx + jinv[(0, 1)] * dy;
    let mut y = yn + jinv[(1, 0)] * dx + jinv[(1, 1)] * dy;
    // One Newton correction with the exact Jacobian at the first-order point.
    let ((fx, fy), j) = cam.distort_with_jacobian(x, y);
    if let Some(ji) = j.try_inverse() {
        let (ex, ey) = (fx - tx, fy - ty);
        x -= ji[(0, 0)] * ex + ji[(0, 1)] * ey;
        y -= ji[(1, 0)] * ex + ji[(1, 1)] * ey;
    }
    (x, y)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{SimConfig, Twin};

    /// The tiled render equals the pixel-by-pixel one (a tile wrongly taken as uniform
    /// would be off by a part of the contrast over some pixel) on a calibration view
    /// (a chessboard and its square corners) and a scan frame (the stripe over the
    /// ball and the table), both cropped to their
    /// central 200 x 152 px (not a multiple of the tile).
    #[test]
    fn tiles_render_exactly_what_the_pixels_do() {
        for (preset, sphere) in [("hp3-chessboard", false), ("hp3-paper", true)] {
            let twin = Twin::new(SimConfig::preset(preset).unwrap()).unwrap();
            let q = if sphere {
                let qs = twin.scan_poses().unwrap();
                qs[qs.len() / 2].clone()
            } else {
                twin.calibration_poses().unwrap()[0].q_deg.clone()
            };
            let scene = twin.scene(&q, sphere).unwrap();
            let ss = twin.cfg.imaging.supersample;
            // the image's central 200 x 152 px
            let mut cam = twin.camera.clone();
            cam.u0 -= f64::from(cam.width / 2 - 100);
            cam.v0 -= f64::from(cam.height / 2 - 76);
            (cam.width, cam.height) = (200, 152);
            let r = Renderer::new(&cam, ss).unwrap();
            let tiled = r.render(&scene);
            let (w, h) = (tiled.width, tiled.height);
            let offs = [
                FinePattern::for_kind(scene.board().kind).offsets(4 * ss),
                FinePattern::for_kind(scene.board().kind).offsets(8 * ss),
            ];
            let mut worst = 0f32;
            for row in 0..h {
                for col in 0..w {
                    let (a, l) = r.pixel(&scene, row, col, [&offs[0], &offs[1]]);
                    let i = row * w + col;
                    worst = worst
                        .max((a - tiled.ambient[i]).abs())
                        .max((l - tiled.laser[i]).abs());
                }
            }
            let uniform = r
                .tiles
                .iter()
                .filter(|(c, a)| {
                    matches!(
                        scene.classify(&Vector3::new(c[0], c[1], 1.0), *a),
                        Footprint::Uniform(_)
                    )
                })
                .count();
            let lit = tiled.laser.iter().filter(|&&l| l > 0.0).count();
            println!(
                "{preset}: {uniform} of {} tiles uniform, {lit} lit pixels, worst {worst:e}",
                r.tiles.len()
            );
            assert!(worst <= 1e-6, "{preset}: {worst}");
            // both paths are exercised
            assert!(
                uniform > r.tiles.len() / 5 && uniform < r.tiles.len(),
                "{preset}: {uniform}"
            );
            assert!(!sphere || lit > 100, "{preset}: {lit} lit pixels");
        }
    }

    #[test]
    fn multi_jittered_pattern_is_stratified_three_ways() {
        let m = 16;
        let p = FinePattern::MultiJittered.offsets(m);
        assert_eq!(p.len(), m * m);
        let f = (m * m) as f64;
        let mut cols = vec![0; m * m];
        let mut rows = vec![0; m * m];
        let mut cells = vec![0; m * m];
        for &(x, y) in &p {
            assert!(x > -0.5 && x < 0.5 && y > -0.5 && y < 0.5);
            let (fx, fy) = (((x + 0.5) * f) as usize, ((y + 0.5) * f) as usize);
            cols[fx] += 1;
            rows[fy] += 1;
            cells[(fy / m) * m + fx / m] += 1;
        }
        assert!(cols.iter().chain(&rows).chain(&cells).all(|&c| c == 1));
        // fixed: the same pattern every time
        assert_eq!(p, FinePattern::MultiJittered.offsets(m));
        // the grid keeps the historical order: rows of du, one dv after another
        let g = FinePattern::Grid.offsets(4);
        assert_eq!(g[1], (-0.125, -0.375));
        assert_eq!(g[4], (-0.375, -0.125));
    }
}
