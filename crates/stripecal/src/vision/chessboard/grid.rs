//! Grid stage on one pyramid level: lattice coordinates for the candidates from
//! neighbourhood topology and square colours.
//!
//! 1. Seed: a candidate whose nearest candidates of the opposite polarity (light axis a
//!    quarter turn away) form a lattice cross (two opposite pairs), with the four
//!    squares around it alternating in colour. The seed fixes the colour phase.
//! 2. Growth: every free lattice site next to the grid is predicted by an affine fit of
//!    the sites within two (else three) steps; the nearest free candidate within 0.3
//!    local pitches whose polarity fits the site's parity takes it if the links to its
//!    grown neighbours are chessboard edges (the squares on either side have the
//!    phase's colours, dark clearly below light) and none contradicts. Rounds repeat
//!    until nothing is added; the extent is capped a little beyond the board's.
//! 3. Check: each site is predicted from the others without itself (leave-one-out);
//!    sites farther than 0.25 local pitches are dropped.
//!
//! Several seeds are grown (best first, from candidates not yet in a grid), so a second
//! board in the image is seen.

use super::candidates::Cand;
use super::cells::{check_link, patch_median, Check, Link};
use super::image::Gray;
use super::lattice::{extent, norm, predict_any, Buckets, Coord, CoordMap};

/// A grown grid on one level (positions in the level's pixels).
#[derive(Debug, Clone)]
pub(crate) struct Grid {
    /// Site -> candidate index.
    pub at: CoordMap<usize>,
    /// Cell `(i, j)` is dark iff `i + j + phase` is even.
    pub phase: u8,
    /// Sites grown before the leave-one-out check, and those it removed.
    pub grown: usize,
    pub inconsistent: usize,
}

/// Largest seed-to-neighbour distance searched, level px (larger squares are found on
/// a coarser level).
const MAX_PITCH: f64 = 48.0;

pub(crate) struct Ctx<'a> {
    pub g: &'a Gray,
    pub cands: &'a [Cand],
    pub pos: Vec<[f64; 2]>,
    pub index: Buckets,
    /// Noise sigma on this level.
    pub noise: f32,
    /// Largest extent (sites) in either lattice direction.
    pub max_extent: i32,
}

impl<'a> Ctx<'a> {
    pub fn new(g: &'a Gray, cands: &'a [Cand], noise: f32, max_extent: i32) -> Ctx<'a> {
        let pos: Vec<[f64; 2]> = cands.iter().map(|c| [c.x as f64, c.y as f64]).collect();
        let index = Buckets::new(&pos, g.w, g.h, 16.0);
        Ctx {
            g,
            cands,
            pos,
            index,
            noise,
            max_extent,
        }
    }

    /// Darkness margin required between the two squares beside a link of `a` and `b`.
    fn thr(&self, a: usize, b: usize) -> f32 {
        let c = 0.5 * (self.cands[a].contrast + self.cands[b].contrast);
        (0.3 * c).max(3.0 * self.noise)
    }

    /// Polarity agreement of two candidates: about 1 when their light axes agree,
    /// about -1 a quarter turn apart.
    fn pol(&self, a: usize, b: usize) -> f32 {
        let (p, q) = (self.cands[a].dir, self.cands[b].dir);
        p[0] * q[0] + p[1] * q[1]
    }
}

/// Initial sites of a seed: `(site, candidate)`.
type Seed = Vec<(Coord, usize)>;

/// The geometry of a seed around candidate `s`: its initial sites, the image vectors to
/// its `+i` and `+j` neighbours (for [`quadrant_phase`], which decides whether it is a
/// seed at all) and its score, a lower score is better. A cross (four neighbours in
/// two opposite pairs) scores below 1; boards with only two rows or columns of corners
/// have none, so an L (two neighbours and the diagonal corner of the square between
/// them) is tried next, scored 10 higher.
fn seed(ctx: &Ctx, s: usize) -> Option<(Seed, [[f64; 2]; 2], f64)> {
    let p = ctx.pos[s];
    let mut near: Vec<(f64, usize)> = Vec::new();
    ctx.index.visit(p, MAX_PITCH, |k| {
        if k == s || ctx.pol(s, k) > -0.3 {
            return;
        }
        let d2 = (ctx.pos[k][0] - p[0]).powi(2) + (ctx.pos[k][1] - p[1]).powi(2);
        if (4.0..=MAX_PITCH * MAX_PITCH).contains(&d2) {
            near.push((d2, k));
        }
    });
    if near.len() < 2 {
        return None;
    }
    near.sort_by(|a, b| a.0.total_cmp(&b.0));
    near.truncate(6);
    let v: Vec<[f64; 2]> = near
        .iter()
        .map(|&(_, k)| [ctx.pos[k][0] - p[0], ctx.pos[k][1] - p[1]])
        .collect();
    let k = |x: usize| near[x].1;
    if let Some(([a, a2, b, b2], score)) = best_cross(&v) {
        let sites = vec![
            ((0, 0), s),
            ((1, 0), k(a)),
            ((-1, 0), k(a2)),
            ((0, 1), k(b)),
            ((0, -1), k(b2)),
        ];
        return Some((sites, [v[a], v[b]], score));
    }
    let (a, b, d, score) = best_l(ctx, s, &v)?;
    Some((
        vec![((0, 0), s), ((1, 0), k(a)), ((0, 1), k(b)), ((1, 1), d)],
        [v[a], v[b]],
        10.0 + score,
    ))
}

fn cosine(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] * b[0] + a[1] * b[1]) / (norm(a) * norm(b))
}

/// The most symmetric cross among the neighbour vectors: `([+i, -i, +j, -j], score)`.
fn best_cross(v: &[[f64; 2]]) -> Option<([usize; 4], f64)> {
    let pair_ok = |a: usize, b: usize| {
        let ratio = norm(v[a]) / norm(v[b]);
        cosine(v[a], v[b]) < -0.85 && (0.6..=1.0 / 0.6).contains(&ratio)
    };
    let sym = |a: usize, b: usize| norm([v[a][0] + v[b][0], v[a][1] + v[b][1]]) / norm(v[a]);
    let mut best: Option<([usize; 4], f64)> = None;
    let n = v.len();
    for a in 0..n {
        for a2 in a + 1..n {
            if !pair_ok(a, a2) {
                continue;
            }
            for b in 0..n {
                for b2 in b + 1..n {
                    if [a, a2].contains(&b) || [a, a2].contains(&b2) || !pair_ok(b, b2) {
                        continue;
                    }
                    if cosine(v[a], v[b]).abs() > 0.85 {
                        continue;
                    }
                    // nearer neighbours are preferred: a cross of farther candidates
                    // around a closer one is not this corner's
                    let score =
                        0.1 * (sym(a, a2) + sym(b, b2)) + 0.1 * (a + a2 + b + b2) as f64 / 6.0;
                    if best.is_none_or(|(_, sc)| score < sc) {
                        best = Some(([a, a2, b, b2], score));
                    }
                }
            }
        }
    }
    best
}

/// The best L: neighbours `a`, `b` and the candidate `d` at the square's far corner.
fn best_l(ctx: &Ctx, s: usize, v: &[[f64; 2]]) -> Option<(usize, usize, usize, f64)> {
    let p = ctx.pos[s];
    let mut best: Option<(usize, usize, usize, f64)> = None;
    for a in 0..v.len() {
        for b in a + 1..v.len() {
            let ratio = norm(v[a]) / norm(v[b]);
            if cosine(v[a], v[b]).abs() > 0.85 || !(0.5..=2.0).contains(&ratio) {
                continue;
            }
            let q = [p[0] + v[a][0] + v[b][0], p[1] + v[a][1] + v[b][1]];
            let tol = 0.25 * norm(v[a]).min(norm(v[b]));
            let mut far: Option<(f64, usize)> = None;
            ctx.index.visit(q, tol, |k| {
                let d2 = (ctx.pos[k][0] - q[0]).powi(2) + (ctx.pos[k][1] - q[1]).powi(2);
                if k != s
                    && ctx.pol(s, k) > 0.3
                    && d2 < tol * tol
                    && far.is_none_or(|(bd, _)| d2 < bd)
                {
                    far = Some((d2, k));
                }
            });
            let Some((d2, d)) = far else { continue };
            let score = d2.sqrt() / tol + 0.1 * (a + b) as f64;
            if best.is_none_or(|x| score < x.3) {
                best = Some((a, b, d, score));
            }
        }
    }
    best
}

/// Colour phase from the four squares around seed `s` with edge vectors `a`, `b`
/// (the squares alternate clearly), or `None`.
fn quadrant_phase(ctx: &Ctx, s: usize, a: [f64; 2], b: [f64; 2]) -> Option<u8> {
    let p = ctx.pos[s];
    let neg = |x: [f64; 2]| [-x[0], -x[1]];
    let cell = |x: [f64; 2], y: [f64; 2]| {
        let c = [p[0] + 0.5 * (x[0] + y[0]), p[1] + 0.5 * (x[1] + y[1])];
        patch_median(ctx.g, c, x, y, 0.2, 4)
    };
    let (c00, c10, c11, c01) = (
        cell(a, b)?,
        cell(neg(a), b)?,
        cell(neg(a), neg(b))?,
        cell(a, neg(b))?,
    );
    let thr = (0.3 * ctx.cands[s].contrast).max(3.0 * ctx.noise);
    if c00.max(c11) + thr <= c10.min(c01) {
        Some(0) // cells (0, 0) and (-1, -1) dark
    } else if c10.max(c01) + thr <= c00.min(c11) {
        Some(1)
    } else {
        None
    }
}

/// Whether adding site `t` at candidate `k` keeps the extent within the cap.
fn fits(ext: (i32, i32, i32, i32), t: Coord, cap: i32) -> bool {
    let ei = ext.1.max(t.0) - ext.0.min(t.0) + 1;
    let ej = ext.3.max(t.1) - ext.2.min(t.1) + 1;
    ei <= cap && ej <= cap
}

/// Checks candidate `k` for site `t`: polarity against the grown neighbours and the
/// links to its 4-neighbours.
fn accepts(ctx: &Ctx, at: &CoordMap<usize>, phase: u8, t: Coord, k: usize) -> bool {
    let mut pol = 0f32;
    for di in -1..=1 {
        for dj in -1..=1 {
            if let Some(&n) = at.get(&(t.0 + di, t.1 + dj)) {
                let same = (di + dj).rem_euclid(2) == 0;
                pol += if same { ctx.pol(k, n) } else { -ctx.pol(k, n) };
            }
        }
    }
    if pol <= 0.0 {
        return false;
    }
    let mut pass = 0;
    for d in [(1, 0), (-1, 0), (0, 1), (0, -1)] {
        let nb = (t.0 + d.0, t.1 + d.1);
        let Some(&n) = at.get(&nb) else { continue };
        // perpendicular step at the neighbour, from its own neighbours
        let e = if d.0 != 0 { (0, 1) } else { (1, 0) };
        let perp = match (
            at.get(&(nb.0 + e.0, nb.1 + e.1)),
            at.get(&(nb.0 - e.0, nb.1 - e.1)),
        ) {
            (Some(&q), _) => [ctx.pos[q][0] - ctx.pos[n][0], ctx.pos[q][1] - ctx.pos[n][1]],
            (None, Some(&q)) => [ctx.pos[n][0] - ctx.pos[q][0], ctx.pos[n][1] - ctx.pos[q][1]],
            _ => continue,
        };
        let link = Link {
            a: t,
            b: nb,
            pa: ctx.pos[k],
            pb: ctx.pos[n],
            perp,
        };
        match check_link(ctx.g, &link, phase, ctx.thr(k, n)) {
            Check::Pass => pass += 1,
            Check::Fail => return false,
            Check::Unknown => {}
        }
    }
    pass > 0
}

fn grow(ctx: &Ctx, seed: &Seed, phase: u8, taken: &mut [bool]) -> CoordMap<usize> {
    let mut at: CoordMap<usize> = CoordMap::default();
    for &(c, k) in seed {
        at.insert(c, k);
        taken[k] = true;
    }
    let Some(mut ext) = extent(at.keys()) else {
        return at;
    };
    let mut targets: Vec<Coord> = Vec::new();
    loop {
        targets.clear();
        for &(i, j) in at.keys() {
            for d in [(1, 0), (-1, 0), (0, 1), (0, -1)] {
                let t = (i + d.0, j + d.1);
                if !at.contains_key(&t) && fits(ext, t, ctx.max_extent) {
                    targets.push(t);
                }
            }
        }
        targets.sort_unstable();
        targets.dedup();
        let mut proposals: Vec<(f64, Coord, usize)> = Vec::new();
        for &t in &targets {
            let Some(l) = predict_any(&at, &ctx.pos, t) else {
                continue;
            };
            let tol = 0.3 * l.pitch();
            let mut best: Option<(f64, usize)> = None;
            ctx.index.visit(l.p, tol, |k| {
                if taken[k] {
                    return;
                }
                let d2 = (ctx.pos[k][0] - l.p[0]).powi(2) + (ctx.pos[k][1] - l.p[1]).powi(2);
                if d2 < tol * tol && best.is_none_or(|(bd, _)| d2 < bd) {
                    best = Some((d2, k));
                }
            });
            if let Some((d2, k)) = best {
                proposals.push((d2.sqrt() / l.pitch(), t, k));
            }
        }
        proposals.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut added = 0;
        for (_, t, k) in proposals {
            if taken[k] || at.contains_key(&t) || !fits(ext, t, ctx.max_extent) {
                continue;
            }
            if !accepts(ctx, &at, phase, t, k) {
                continue;
            }
            at.insert(t, k);
            taken[k] = true;
            ext = (
                ext.0.min(t.0),
                ext.1.max(t.0),
                ext.2.min(t.1),
                ext.3.max(t.1),
            );
            added += 1;
        }
        if added == 0 {
            break;
        }
    }
    at
}

/// Removes sites that their neighbours do not predict (leave-one-out); returns how
/// many were removed.
pub(crate) fn leave_one_out(at: &mut CoordMap<usize>, pos: &[[f64; 2]], tol: f64) -> usize {
    let mut keys: Vec<Coord> = at.keys().copied().collect();
    keys.sort_unstable();
    let mut bad: Vec<Coord> = Vec::new();
    for t in keys {
        let Some(k) = at.remove(&t) else { continue };
        let pred = predict_any(at, pos, t);
        at.insert(t, k);
        let ok = pred.is_some_and(|l| {
            let d = ((pos[k][0] - l.p[0]).powi(2) + (pos[k][1] - l.p[1]).powi(2)).sqrt();
            d <= tol * l.pitch()
        });
        if !ok {
            bad.push(t);
        }
    }
    for t in &bad {
        at.remove(t);
    }
    bad.len()
}

/// Grids on this level, largest first (at most `max_grids`).
pub(crate) fn find_grids(ctx: &Ctx, max_grids: usize) -> Vec<Grid> {
    let n = ctx.cands.len();
    // seeds among the strongest candidates, best first; the colours of a seed's squares
    // (which decide whether it is one) are looked at only when it is reached (a few
    // of up to 400 are)
    let mut seeds: Vec<(f64, Seed, [[f64; 2]; 2])> = Vec::new();
    for s in 0..n.min(400) {
        if let Some((sites, ab, score)) = seed(ctx, s) {
            seeds.push((score, sites, ab));
        }
    }
    seeds.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut used = vec![false; n];
    let mut grids: Vec<Grid> = Vec::new();
    let mut tries = 0;
    for (_, sites, [a, b]) in &seeds {
        if tries >= 3 * max_grids + 3 || grids.len() >= max_grids {
            break;
        }
        if sites.iter().any(|&(_, k)| used[k]) {
            continue;
        }
        let Some(phase) = quadrant_phase(ctx, sites[0].1, *a, *b) else {
            continue;
        };
        tries += 1;
        let mut taken = used.clone();
        let mut at = grow(ctx, sites, phase, &mut taken);
        let grown = at.len();
        let inconsistent = leave_one_out(&mut at, &ctx.pos, 0.25);
        for &k in at.values() {
            used[k] = true;
        }
        for &(_, k) in sites {
            used[k] = true;
        }
        if at.len() >= 4 {
            grids.push(Grid {
                at,
                phase,
                grown,
                inconsistent,
            });
        }
    }
    grids.sort_by_key(|g| std::cmp::Reverse(g.at.len()));
    grids
}
