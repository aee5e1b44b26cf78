//! Which peak of a scan line is the stripe when it holds several: the one that
//! continues the line. A reflection, a second laser line or a bright edge of the scene
//! is not a reason to drop the scan line; the line is the longest, strongest chain of
//! peaks through the neighbouring scan lines.
//!
//! ## Method
//!
//! 1. Every scan line's kept runs (at most [`super::ridge::MAX_RUNS`], strongest
//!    first) are nodes at their peak pixel, weighted by their brightest value times the
//!    width of the plateau at that value about the peak (an unsaturated line by its
//!    brightness, a saturated one by its plateau's width; the extractor measures it on
//!    the scan line).
//! 2. Chains, scan line by scan line: a node joins the chain whose last node lies at
//!    most [`MAX_GAP`] scan lines back and at most `max_jump * gap + slack` px away
//!    along the scan line (nearest pairs first, one node per chain and line); a node
//!    that joins none starts a chain. A chain's score is the sum of its nodes' areas.
//! 3. A scan line's peak is its comparable run (at least `second_peak_ratio` of the
//!    strongest, as the single-peak test reads it) whose chain is heaviest: the mean
//!    weight per node (a line broken by dark print keeps its weight; a reflection is
//!    weaker all along, if only by a little when both are saturated: their plateaus
//!    differ in width). Only chains of at least [`MIN_DECIDING`] nodes on 80 % of the
//!    scan lines they span take part (peaks of noise chain through the allowed gaps, a
//!    line does not). The heaviest wins when its mean exceeds the runner-up's by
//!    [`TIE_SIGMAS`] standard errors of the difference and by [`MIN_MARGIN`]; otherwise
//!    the scan line stays ambiguous (two lines of the same weight: no decision). Comparable runs left out are counted
//!    as reflections ([`super::RejectCounts::reflections`]).
//! 4. A chain that lost such a decision more often than it won (and on at least half of
//!    [`MIN_DECIDING`] scan lines) is a reflection: its scan lines where it stands
//!    alone (the line itself dimmed there, by dark print say) give no point either
//!    ([`super::RejectCounts::reflection_only`]).
//!
//! Scan lines with a single comparable run get that run, as without this step, except
//! by step 4; the chains run only for an image where some scan line is ambiguous.

use super::ridge::{LineCand, LineReject, Run};

/// The largest gap of a chain, scan lines.
pub const MAX_GAP: u32 = 3;
/// The heavier of two chains decides only when its mean weight per scan line exceeds
/// the other's by this many standard errors of the difference...
pub const TIE_SIGMAS: f64 = 3.0;
/// ...and by at least this fraction (two lines of the same weight stay ambiguous).
pub const MIN_MARGIN: f64 = 0.03;
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
    /// Sum of the squared areas (the spread of the chain's weight per scan line).
    score_sq: f64,
    len: u32,
}

impl Chain {
    /// The mean area per node and its standard error.
    fn mean(&self) -> (f64, f64) {
        let n = f64::from(self.len.max(1));
        let m = self.score as f64 / n;
        let var = (self.score_sq / n - m * m).max(0.0);
        (m, (var / n).sqrt())
    }
}

/// The decision of one scan line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Decision {
    /// The peak pixel, and whether a comparable run was left out as a reflection.
    Peak(usize, bool),
    /// Two comparable peaks that the line's continuity does not decide between (the
    /// likelier first): kept both where the caller can decide later (the board plane's
    /// consensus of a calibration), a rejected scan line otherwise.
    Ambiguous(usize, usize),
    Reject(LineReject),
}

/// Reusable buffers of the chain decision.
#[derive(Debug, Clone, Default)]
pub(super) struct Chains {
    nodes: Vec<Node>,
    chains: Vec<Chain>,
    pairs: Vec<(f32, usize, usize)>,
    active: Vec<usize>,
    /// Per chain: scan lines where it won and lost a decision.
    record: Vec<(u32, u32)>,
}

impl Chains {
    /// The decision of every scan line `cands[l]` (module docs) into `out`.
    /// `weight(line, run)` is a run's weight (module docs, step 1).
    pub(super) fn decide(
        &mut self,
        cands: &[LineCand],
        ratio: f32,
        max_jump: f32,
        slack: f32,
        weight: impl Fn(usize, &Run) -> u32,
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
        self.link(cands, max_jump, slack, weight);
        let mut k = 0;
        for c in cands {
            let n = c.runs().len();
            let nodes = &self.nodes[k..k + n];
            k += n;
            out.push(self.line_decision(c, nodes, ratio));
        }
        self.drop_reflections(cands, ratio, out);
    }

    /// Step 4 of the module docs: where a chain lost to a heavier one more often than it
    /// won, its scan lines where it stands alone are a reflection's too.
    fn drop_reflections(&mut self, cands: &[LineCand], ratio: f32, out: &mut [Decision]) {
        self.record.clear();
        self.record.resize(self.chains.len(), (0, 0));
        let chain_at = |nodes: &[Node], runs: &[Run], pk: usize| {
            runs.iter()
                .zip(nodes)
                .find(|(r, _)| r.peak() == pk)
                .map(|(_, n)| n.chain as usize)
        };
        let mut k = 0;
        for (c, d) in cands.iter().zip(out.iter()) {
            let runs = c.runs();
            let nodes = &self.nodes[k..k + runs.len()];
            k += runs.len();
            if let Decision::Peak(pk, true) = *d {
                let best = runs.first().map_or(0.0, |r| r.strength_f32());
                for (r, n) in runs.iter().zip(nodes) {
                    if r.strength_f32() < ratio * best {
                        continue;
                    }
                    let e = &mut self.record[n.chain as usize];
                    if r.peak() == pk {
                        e.0 += 1;
                    } else {
                        e.1 += 1;
                    }
                }
            }
        }
        let mut k = 0;
        for (c, d) in cands.iter().zip(out.iter_mut()) {
            let runs = c.runs();
            let nodes = &self.nodes[k..k + runs.len()];
            k += runs.len();
            if let Decision::Peak(pk, false) = *d {
                if let Some(ch) = chain_at(nodes, runs, pk) {
                    let (won, lost) = self.record[ch];
                    if lost > won && 2 * lost >= MIN_DECIDING {
                        *d = Decision::Reject(LineReject::Reflection);
                    }
                }
            }
        }
    }

    /// Steps 1 and 2 of the module docs.
    fn link(
        &mut self,
        cands: &[LineCand],
        max_jump: f32,
        slack: f32,
        weight: impl Fn(usize, &Run) -> u32,
    ) {
        self.nodes.clear();
        self.chains.clear();
        self.active.clear();
        for (li, c) in cands.iter().enumerate() {
            let l = li as u32;
            let first = self.nodes.len();
            for r in c.runs() {
                self.nodes.push(Node {
                    pos: r.peak() as f32,
                    area: weight(li, r),
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
                ch.score_sq += f64::from(n.area).powi(2);
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
                        score_sq: f64::from(n.area).powi(2),
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
        // (mean, its standard error, peak) of the deciding chains of the comparable runs
        let mut cands: [(f64, f64, usize); super::ridge::MAX_RUNS] = [(0.0, 0.0, 0); 4];
        let (mut nc, mut comparable) = (0usize, 0usize);
        for (r, n) in runs.iter().zip(nodes) {
            if r.strength_f32() < ratio * best {
                continue;
            }
            comparable += 1;
            let ch = &self.chains[n.chain as usize];
            // a short or gappy chain does not decide
            let span = ch.last_line - ch.first_line + 1;
            if ch.len >= MIN_DECIDING && 5 * ch.len >= 4 * span {
                let (m, se) = ch.mean();
                cands[nc] = (m, se, r.peak());
                nc += 1;
            }
        }
        if comparable == 1 {
            return Decision::Peak(runs[0].peak(), false);
        }
        let c = &mut cands[..nc];
        c.sort_by(|a, b| b.0.total_cmp(&a.0));
        // the two strongest comparable runs, when no chain decides
        let undecided = || match runs {
            [a, b, ..] => Decision::Ambiguous(a.peak(), b.peak()),
            _ => Decision::Reject(LineReject::Multiple),
        };
        match c {
            [] => undecided(),
            // one deciding chain: the others are spots or noise
            [one] => Decision::Peak(one.2, true),
            [a, b, ..] => {
                // the heavier chain wins when it is heavier beyond doubt: by TIE_SIGMAS
                // standard errors of the difference of the two means
                let sd = (a.1 * a.1 + b.1 * b.1).sqrt();
                if a.0 - b.0 > TIE_SIGMAS * sd && a.0 > b.0 * (1.0 + MIN_MARGIN) {
                    Decision::Peak(a.2, true)
                } else {
                    Decision::Ambiguous(a.2, b.2)
                }
            }
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
        ch.decide(&cands, 0.5, 4.0, 5.0, |_, r| r.weight(), &mut out);
        for (l, d) in out.iter().enumerate() {
            match d {
                Decision::Peak(pk, refl) => {
                    let want = 40.0 + 0.1 * l as f64;
                    assert!((*pk as f64 - want).abs() <= 1.0, "line {l}: {pk}");
                    assert!(*refl, "line {l}");
                }
                other => panic!("line {l}: {other:?}"),
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
        Chains::default().decide(&cands, 0.5, 4.0, 5.0, |_, r| r.weight(), &mut out);
        assert!(out
            .iter()
            .all(|d| matches!(d, Decision::Ambiguous(a, b) if a.abs_diff(*b) == 40)));
    }
}
