//! Which peak of a scan line is the stripe when it holds several: the one that
//! continues the line. A reflection, a second laser line or a bright edge of the scene
//! is not a reason to drop the scan line; the line is the longest, strongest chain of
//! peaks through the neighbouring scan lines.
//!
//! ## Method
//!
//! 1. Every scan line's kept runs (at most [`super::ridge::MAX_RUNS`], strongest
//!    first) are nodes at their peak pixel, weighted by their area (the sum of their
//!    ridge responses: a wide or saturated line outweighs a narrow one of the same
//!    height).
//! 2. Chains, scan line by scan line: a node joins the chain whose last node lies at
//!    most [`MAX_GAP`] scan lines back and at most `max_jump * gap + slack` px away
//!    along the scan line (nearest pairs first, one node per chain and line); a node
//!    that joins none starts a chain. A chain's score is the sum of its nodes' areas.
//! 3. A scan line's peak is its comparable run (at least `second_peak_ratio` of the
//!    strongest, as the single-peak test reads it) whose chain scores highest. When the
//!    runner-up's chain scores at least [`TIE`] of that, the scan line stays ambiguous
//!    (two lines of equal weight: no decision), and so it does when no chain of its
//!    comparable runs has [`MIN_DECIDING`] nodes on at least 80 % of the scan lines it
//!    spans (peaks of noise chain through the allowed gaps, a line does not). Comparable runs left out are counted
//!    as reflections ([`super::RejectCounts::reflections`]).
//!
//! Scan lines with a single comparable run get that run, as without this step; the
//! chains run only for an image where some scan line is ambiguous.

use super::ridge::{LineCand, LineReject};

/// The largest gap of a chain, scan lines.
pub const MAX_GAP: u32 = 3;
/// A runner-up chain scoring at least this share of the best leaves the scan line
/// ambiguous.
pub const TIE: f64 = 0.8;
/// A chain decides an ambiguous scan line only when it has at least this many nodes
/// (a real line crosses tens of scan lines; peaks of noise rarely chain this far).
pub const MIN_DECIDING: u32 = 16;

/// One peak of a scan line in the chains.
#[derive(Debug, Clone, Copy)]
pub(super) struct Node {
    pos: f32,
    area: u32,
    chain: u32,
}

/// A chain's running state.
#[derive(Debug, Clone, Copy)]
pub(super) struct Chain {
    first_line: u32,
    last_line: u32,
    last_pos: f32,
    score: u64,
    len: u32,
}

/// The decision of one scan line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Decision {
    /// The peak pixel, and whether a comparable run was left out as a reflection.
    Peak(usize, bool),
    Reject(LineReject),
}

/// Reusable buffers of the chain decision.
#[derive(Debug, Clone, Default)]
pub(super) struct Chains {
    nodes: Vec<Node>,
    chains: Vec<Chain>,
    pairs: Vec<(f32, usize, usize)>,
    active: Vec<usize>,
}

impl Chains {
    /// The decision of every scan line `cands[l]` (module docs) into `out`.
    pub(super) fn decide(
        &mut self,
        cands: &[LineCand],
        ratio: f32,
        max_jump: f32,
        slack: f32,
        out: &mut Vec<Decision>,
    ) {
        out.clear();
        let ambiguous = cands
            .iter()
            .any(|c| matches!(c.verdict(ratio), Err(LineReject::Multiple)));
        if !ambiguous {
            out.extend(cands.iter().map(|c| match c.verdict(ratio) {
                Ok(pk) => Decision::Peak(pk, false),
                Err(e) => Decision::Reject(e),
            }));
            return;
        }
        self.link(cands, max_jump, slack);
        let mut k = 0;
        for c in cands {
            let n = c.runs().len();
            let nodes = &self.nodes[k..k + n];
            k += n;
            out.push(self.line_decision(c, nodes, ratio));
        }
    }

    /// Steps 1 and 2 of the module docs.
    fn link(&mut self, cands: &[LineCand], max_jump: f32, slack: f32) {
        self.nodes.clear();
        self.chains.clear();
        self.active.clear();
        for (l, c) in cands.iter().enumerate() {
            let l = l as u32;
            let first = self.nodes.len();
            for r in c.runs() {
                self.nodes.push(Node {
                    pos: r.peak() as f32,
                    area: r.area(),
                    chain: u32::MAX,
                });
            }
            let chains = &self.chains;
            self.active.retain(|&i| chains[i].last_line + MAX_GAP >= l);
            self.pairs.clear();
            for (ni, n) in self.nodes[first..].iter().enumerate() {
                for &ci in &self.active {
                    let ch = &self.chains[ci];
                    let gap = (l - ch.last_line) as f32;
                    let d = (n.pos - ch.last_pos).abs();
                    if d <= max_jump * gap + slack {
                        self.pairs.push((d + gap, first + ni, ci));
                    }
                }
            }
            self.pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
            for &(_, ni, ci) in &self.pairs {
                if self.nodes[ni].chain != u32::MAX || self.chains[ci].last_line == l {
                    continue;
                }
                let n = &mut self.nodes[ni];
                n.chain = ci as u32;
                let ch = &mut self.chains[ci];
                ch.last_line = l;
                ch.last_pos = n.pos;
                ch.score += u64::from(n.area);
                ch.len += 1;
            }
            for n in &mut self.nodes[first..] {
                if n.chain == u32::MAX {
                    n.chain = self.chains.len() as u32;
                    self.active.push(self.chains.len());
                    self.chains.push(Chain {
                        first_line: l,
                        last_line: l,
                        last_pos: n.pos,
                        score: u64::from(n.area),
                        len: 1,
                    });
                }
            }
        }
    }

    /// Step 3 of the module docs for one scan line with its nodes.
    fn line_decision(&self, c: &LineCand, nodes: &[Node], ratio: f32) -> Decision {
        let runs = c.runs();
        if runs.is_empty() {
            return Decision::Reject(LineReject::NoPeak);
        }
        let best = runs[0].strength_f32();
        let (mut top, mut second) = (None::<(u64, usize)>, 0u64);
        let mut comparable = 0;
        for (r, n) in runs.iter().zip(nodes) {
            if r.strength_f32() < ratio * best {
                continue;
            }
            comparable += 1;
            let ch = &self.chains[n.chain as usize];
            // a short or gappy chain weighs nothing in the decision
            let span = ch.last_line - ch.first_line + 1;
            let s = if ch.len >= MIN_DECIDING && 5 * ch.len >= 4 * span {
                ch.score
            } else {
                0
            };
            match top {
                Some((t, _)) if s <= t => second = second.max(s),
                Some((t, _)) => {
                    second = t;
                    top = Some((s, r.peak()));
                }
                None => top = Some((s, r.peak())),
            }
        }
        match top {
            Some((t, pk)) if comparable == 1 || (t > 0 && (second as f64) < TIE * t as f64) => {
                Decision::Peak(pk, comparable > 1)
            }
            _ => Decision::Reject(LineReject::Multiple),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::ridge::scan_line_generic;
    use super::*;

    /// Scan lines of a bright line at 40 and a 60 % reflection at 70; every tenth scan
    /// line also holds a brighter spot at 10.
    #[test]
    fn the_peak_that_continues_the_line_wins() {
        let mut cands = Vec::new();
        for l in 0..60usize {
            let mut line = vec![10u8; 100];
            for (x, v) in line.iter_mut().enumerate() {
                let t = (x as f64 - 40.0 - 0.1 * l as f64) / 1.5;
                let r = (x as f64 - 70.0 - 0.1 * l as f64) / 1.5;
                *v = (10.0 + 200.0 * (-0.5 * t * t).exp() + 120.0 * (-0.5 * r * r).exp()).round()
                    as u8;
            }
            if l % 10 == 5 {
                line[10] = 255;
            }
            let mut c = LineCand::default();
            scan_line_generic(&line, 5, 6, &mut c);
            cands.push(c);
        }
        let mut ch = Chains::default();
        let mut out = Vec::new();
        ch.decide(&cands, 0.5, 4.0, 5.0, &mut out);
        for (l, d) in out.iter().enumerate() {
            match d {
                Decision::Peak(pk, refl) => {
                    let want = 40.0 + 0.1 * l as f64;
                    assert!((*pk as f64 - want).abs() <= 1.0, "line {l}: {pk}");
                    assert!(*refl, "line {l}");
                }
                Decision::Reject(e) => panic!("line {l}: {e:?}"),
            }
        }
    }

    /// Two lines of equal weight: every scan line stays ambiguous.
    #[test]
    fn two_equal_lines_stay_ambiguous() {
        let mut cands = Vec::new();
        for _ in 0..30usize {
            let mut line = vec![10u8; 100];
            line[30] = 200;
            line[70] = 200;
            let mut c = LineCand::default();
            scan_line_generic(&line, 5, 6, &mut c);
            cands.push(c);
        }
        let mut out = Vec::new();
        Chains::default().decide(&cands, 0.5, 4.0, 5.0, &mut out);
        assert!(out
            .iter()
            .all(|d| *d == Decision::Reject(LineReject::Multiple)));
    }
}
