//! The parameter vector of the one-stage adjustment: which blocks it holds, where each
//! sits (its dual-number slots and its solver columns), their names, how the vector
//! decodes into parameters, how a step is applied (retraction), and how results and
//! sigmas are read back.
//!
//! ## Blocks
//!
//! | block        | slots | columns (estimated)                  | update            |
//! |--------------|-------|--------------------------------------|-------------------|
//! | camera       | 9     | `fu fv u0 v0` + the model's free `k` | `p + dp`          |
//! | laser plane  | 3     | `a, b, d`                            | `p + dp`          |
//! | `X`, `Z`     | 6 each| rotation vector `w`, translation `t` | `R Exp(w)`, `t+v` |
//! | board scale  | 1     | `s` (every board coordinate times s) | `p + dp`          |
//! | robot        | none  | the DH corrections chosen ([`super::robot`]) | `p + dp`  |
//! | sphere centre| none  | a profiler's sphere centre in the base frame, mm | `p + dp` |
//! | sphere diameter | none | the sphere's diameter, mm (when not declared) | `p + dp` |
//!
//! A profiler ([`super::profile`]) has no camera, laser plane, `Z` or board: those
//! blocks are held (no columns), `X` is `T_hand_sensor`, and its sphere's centre and
//! diameter are slotless global blocks (its residuals have analytic derivatives).
//!
//! The robot block is global but has no slots: its columns follow the other global
//! columns, and a view's residuals reach them through its flange pose (the chain of
//! `X`'s slots, [`super::robot::RobotBlock::flange_jacobians`]).
//!
//! Per-view blocks (one instance per view used):
//!
//! | block        | values | columns (estimated)                 | update            |
//! |--------------|--------|-------------------------------------|-------------------|
//! | robot pose   | 6      | flange-frame correction `D_i`: `w`, `t` | `R Exp(w)`, `t+v` |
//! | image pose   | 6      | the part `e_i` of `D_i` the view's image gets wrong (rad, mm) | `p + dp` |
//! | board pose   | 6      | `T_cam_board(i)` on the bench: `w`, `t` | `R Exp(w)`, `t+v` |
//!
//! The image-pose part ([`super::robot_noise`]) does not enter the chain: only the
//! correction's two priors see it (the robot's on `D_i - e_i`, the image's on `e_i`).
//!
//! The board pose is the bench's ([`super::bench`]): no robot, every view's board pose
//! free. It starts at the view's own pose (not the identity), and reaches the residuals
//! through `Z`'s slots (with `A_i` and `X` the identity, `T_cam_board = Z`).
//!
//! A *slot* is a position in the full set of global parameters (the dual numbers of the
//! Jacobian run over all [`SLOTS`] of them); a *column* is a position in the solver's
//! vector: the estimated global slots packed in block order, then each view's estimated
//! per-view values (view after view, blocks in registration order). A block that is not
//! estimated ([`FreeBlocks`](super::FreeBlocks)) has no columns: its slots keep the starting values
//! (`base`), a per-view block's values the identity. Per-view blocks have no slots: a
//! view's residuals reach them through the slots of the global block they perturb (the
//! robot-pose correction through `X`'s, [`super::robot_noise`]). The laser plane's unit
//! normal is `normalize(n0 + a e1 + b e2)` around the starting normal `n0`
//! ([`PlaneChart`]).
//!
//! A new block is one [`BlockKind`] (its size, names, update and decoding) plus its
//! registration in [`ParamLayout::new`], global or per view.
//!
//! Here the blocks and the layout's queries, encoding, decoding and retraction;
//! [`build`] registers the blocks, [`chart`] is the plane's chart, [`params`] the
//! decoded values.

mod build;
mod chart;
mod params;

pub(super) use chart::PlaneChart;
pub(super) use params::JointParams;

use std::ops::Range;

use nalgebra::{Matrix3, Vector3};

use crate::calib::joint::robot::RobotBlock;
use crate::calib::joint::JointOptions;
use crate::model::geometry::{iso_from_rotvec, matrix_to_rotvec, rotvec_to_matrix, Iso3};

/// Number of slots (the dual-number width of the Jacobian): camera 9, plane 3, X 6, Z 6,
/// board scale 1.
pub(super) const SLOTS: usize = 25;

/// The blocks of the parameter vector, in slot (and column) order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Block {
    /// The camera parameters ([`PARAM_NAMES`](crate::model::camera::PARAM_NAMES) order).
    Camera,
    /// The laser plane's chart coordinates `a, b` and offset `d`, mm.
    Plane,
    /// `X = T_hand_cam`.
    HandCam,
    /// `Z = T_base_board`.
    BaseBoard,
    /// The board's scale `s`: the printed board is `s` times rig.json's.
    BoardScale,
    /// Per view: the correction `D_i` of the robot's flange pose, `A_i' = A_i D_i`.
    RobotPose,
    /// Per view: the part of `D_i` the view's own image gets wrong (rotation rad,
    /// translation mm; [`super::robot_noise`]).
    ImagePose,
    /// Per view, on the bench: the board pose `T_cam_board(i)` ([`super::bench`]).
    BoardPose,
    /// A profiler's sphere centre in the base frame, mm (global, no slots).
    SphereCentre,
    /// A profiler's sphere diameter, mm (global, no slots).
    SphereDiameter,
    /// Corrections to the robot's DH rows (global, no slots).
    Robot,
}

/// How a block's numbers behave.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum BlockKind {
    /// Numbers updated by addition.
    Euclidean,
    /// A rigid transform stored as rotation vector and translation (mm), updated by
    /// `R Exp(w)` (rotation about the transform's own axes) and `t + v`; estimated as a
    /// whole or not at all.
    RigidTransform,
}

/// One registered block.
#[derive(Debug, Clone)]
struct BlockDef {
    block: Block,
    kind: BlockKind,
    /// Names of the block's slots.
    names: Vec<String>,
    /// Which slots (values) are estimated.
    free: Vec<bool>,
    /// One instance per view (no slots) instead of one global block.
    per_view: bool,
    /// A global block without slots (its columns follow the slotted ones).
    slotless: bool,
}

impl BlockDef {
    fn euclidean(block: Block, names: &[&str], free: Vec<bool>) -> BlockDef {
        BlockDef {
            block,
            kind: BlockKind::Euclidean,
            names: names.iter().map(|s| s.to_string()).collect(),
            free,
            per_view: false,
            slotless: false,
        }
    }

    /// The block without slots (its columns follow the slotted ones).
    fn slotless(self) -> BlockDef {
        BlockDef {
            slotless: true,
            ..self
        }
    }

    fn transform(block: Block, prefix: &str, free: bool) -> BlockDef {
        let names = ["wx", "wy", "wz", "tx_mm", "ty_mm", "tz_mm"]
            .iter()
            .map(|s| format!("{prefix}_{s}"))
            .collect();
        BlockDef {
            block,
            kind: BlockKind::RigidTransform,
            names,
            free: vec![free; 6],
            per_view: false,
            slotless: false,
        }
    }

    /// The block once per view.
    fn per_view(self) -> BlockDef {
        BlockDef {
            per_view: true,
            ..self
        }
    }

    /// Number of estimated values.
    fn estimated(&self) -> usize {
        self.free.iter().filter(|f| **f).count()
    }
}

/// A profiler's sphere at the start of its adjustment, and whether its diameter is
/// estimated (the centre always is).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct SphereStart {
    pub centre: Vector3<f64>,
    pub diameter: f64,
    pub diameter_free: bool,
}

/// The layout of the adjustment's parameter vector (module docs).
#[derive(Debug, Clone)]
pub(super) struct ParamLayout {
    blocks: Vec<BlockDef>,
    /// First slot of each global block (per-view blocks: unused).
    slot0: Vec<usize>,
    /// First column of each global block; of a per-view block, its first column within
    /// a view's columns.
    col0: Vec<usize>,
    /// Column of each slot (`None`: fixed).
    col_of_slot: Vec<Option<usize>>,
    /// Every slot's value at the start: the fixed slots keep it.
    base: [f64; SLOTS],
    /// Columns of the global blocks (the per-view columns follow them).
    n_global: usize,
    /// Dataset row of each view (for names); one instance of each per-view block each.
    view_ids: Vec<usize>,
    /// Estimated values per view (all per-view blocks).
    per_view_cols: usize,
    /// The per-view columns' starting values, view after view (the robot-pose
    /// corrections 0, the bench's board poses their starting poses).
    view_base: Vec<f64>,
    /// The laser plane's chart.
    pub chart: PlaneChart,
    /// The robot block (its corrections estimated), when the robot is calibrated.
    pub robot: Option<RobotBlock>,
    /// A profiler's sphere at the start (`None` for a camera).
    sphere: Option<SphereStart>,
}

/// Which per-view pose corrections a layout estimates.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum PoseNoise {
    /// None: the robot poses are exact.
    Off,
    /// The robot-pose correction `D_i` with the robot's prior.
    Robot,
    /// `D_i` and its image-pose part `e_i` ([`super::robot_noise`]).
    RobotAndImage,
}

impl PoseNoise {
    /// The corrections the options ask for.
    pub fn of(opts: &JointOptions) -> PoseNoise {
        match (opts.robot_noise, opts.image_pose_noise) {
            (false, _) => PoseNoise::Off,
            (true, false) => PoseNoise::Robot,
            (true, true) => PoseNoise::RobotAndImage,
        }
    }
}

impl ParamLayout {
    fn index(&self, block: Block) -> usize {
        self.blocks
            .iter()
            .position(|b| b.block == block)
            .expect("every block is registered")
    }

    /// The slots of a global block.
    pub fn slots(&self, block: Block) -> Range<usize> {
        let i = self.index(block);
        debug_assert!(!self.blocks[i].per_view, "{block:?} has no slots");
        self.slot0[i]..self.slot0[i] + self.blocks[i].free.len()
    }

    /// The columns of the robot block (empty without one).
    pub fn robot_columns(&self) -> Range<usize> {
        self.slotless_columns(Block::Robot)
    }

    /// The columns of view `v`'s instance of a per-view block (`None`: not estimated).
    pub fn view_columns(&self, block: Block, v: usize) -> Option<Range<usize>> {
        let i = self.index(block);
        let def = &self.blocks[i];
        debug_assert!(def.per_view, "{block:?} is not per view");
        let len = def.estimated();
        (len > 0 && v < self.view_ids.len()).then(|| {
            let c = self.n_global + v * self.per_view_cols + self.col0[i];
            c..c + len
        })
    }

    /// Whether a per-view block is estimated.
    pub fn per_view_free(&self, block: Block) -> bool {
        self.blocks[self.index(block)].estimated() > 0
    }

    /// Columns of the global blocks (the first ones of the vector).
    pub fn num_global(&self) -> usize {
        self.n_global
    }

    /// Estimated values per view (all per-view blocks together).
    pub fn per_view_len(&self) -> usize {
        self.per_view_cols
    }

    /// Number of views (instances of each per-view block).
    pub fn num_views(&self) -> usize {
        self.view_ids.len()
    }

    /// The column of a slot (`None`: held).
    pub fn column(&self, slot: usize) -> Option<usize> {
        self.col_of_slot[slot]
    }

    /// The column of every slot.
    pub fn columns(&self) -> [Option<usize>; SLOTS] {
        std::array::from_fn(|slot| self.col_of_slot[slot])
    }

    /// Length of the parameter vector.
    pub fn num_params(&self) -> usize {
        self.n_global + self.view_ids.len() * self.per_view_cols
    }

    /// Names of the parameter vector's entries: the global blocks' names, then the
    /// per-view ones as `view{row}_{name}` (`row` the view's dataset row).
    pub fn names(&self) -> Vec<String> {
        let estimated = |b: &BlockDef| -> Vec<String> {
            b.names
                .iter()
                .zip(&b.free)
                .filter(|(_, f)| **f)
                .map(|(n, _)| n.clone())
                .collect()
        };
        let mut names: Vec<String> = self
            .blocks
            .iter()
            .filter(|b| !b.per_view)
            .flat_map(estimated)
            .collect();
        for id in &self.view_ids {
            for b in self.blocks.iter().filter(|b| b.per_view) {
                names.extend(estimated(b).iter().map(|n| format!("view{id}_{n}")));
            }
        }
        names
    }

    /// The parameter vector of the start: its estimated slots, then the per-view
    /// blocks at their starts (the robot-pose corrections at the identity, the bench's
    /// board poses at their starting poses).
    pub fn encode(&self) -> Vec<f64> {
        let mut p: Vec<f64> = (0..SLOTS)
            .filter(|&s| self.col_of_slot[s].is_some())
            .map(|s| self.base[s])
            .collect();
        // The slotless blocks: the sphere at its start, the robot corrections at zero.
        if let Some(sp) = &self.sphere {
            p.extend_from_slice(sp.centre.as_slice());
            if sp.diameter_free {
                p.push(sp.diameter);
            }
        }
        p.resize(self.n_global, 0.0);
        p.extend_from_slice(&self.view_base);
        debug_assert_eq!(p.len(), self.num_params());
        p
    }

    /// Every slot's value for the parameter vector `p` (held slots from the start).
    pub fn full(&self, p: &[f64]) -> [f64; SLOTS] {
        let mut v = self.base;
        for (slot, col) in self.col_of_slot.iter().enumerate() {
            if let Some(c) = col {
                v[slot] = p[*c];
            }
        }
        v
    }

    /// The parameters of vector `p`.
    pub fn decode(&self, p: &[f64]) -> JointParams {
        let v = self.full(p);
        let mut cam = [0.0; 9];
        cam.copy_from_slice(&v[self.slots(Block::Camera)]);
        let o = self.slots(Block::Plane).start;
        let n = self.chart.raw_normal(v[o], v[o + 1]);
        let x = self.slots(Block::HandCam).start;
        let z = self.slots(Block::BaseBoard).start;
        JointParams {
            cam,
            plane_n: n / n.norm(),
            plane_d: v[o + 2],
            x_rot: rotvec_to_matrix(&Vector3::new(v[x], v[x + 1], v[x + 2])),
            x_t: Vector3::new(v[x + 3], v[x + 4], v[x + 5]),
            z_rot: rotvec_to_matrix(&Vector3::new(v[z], v[z + 1], v[z + 2])),
            z_t: Vector3::new(v[z + 3], v[z + 4], v[z + 5]),
            scale: v[self.slots(Block::BoardScale).start],
            corrections: self.view_transforms(p, Block::RobotPose),
            image_pose: (0..self.num_views())
                .map_while(|i| self.view_columns(Block::ImagePose, i))
                .map(|c| std::array::from_fn(|k| p[c.start + k]))
                .collect(),
            board_poses: self.view_transforms(p, Block::BoardPose),
            robot: p[self.robot_columns()].to_vec(),
        }
    }

    /// The columns of a global slotless block (empty when not estimated).
    pub fn slotless_columns(&self, block: Block) -> Range<usize> {
        let i = self.index(block);
        debug_assert!(self.blocks[i].slotless, "{block:?} has slots");
        self.col0[i]..self.col0[i] + self.blocks[i].estimated()
    }

    /// A profiler's sphere centre of `p` (zero for a camera).
    pub fn sphere_centre(&self, p: &[f64]) -> Vector3<f64> {
        let c = self.slotless_columns(Block::SphereCentre);
        if c.is_empty() {
            return self.sphere.map_or(Vector3::zeros(), |s| s.centre);
        }
        Vector3::new(p[c.start], p[c.start + 1], p[c.start + 2])
    }

    /// A profiler's sphere diameter of `p` (the start's when held; zero for a camera).
    pub fn sphere_diameter(&self, p: &[f64]) -> f64 {
        let c = self.slotless_columns(Block::SphereDiameter);
        if c.is_empty() {
            return self.sphere.map_or(0.0, |s| s.diameter);
        }
        p[c.start]
    }

    /// Every view's instance of a per-view transform block of `p` (empty when not
    /// estimated).
    fn view_transforms(&self, p: &[f64], block: Block) -> Vec<(Matrix3<f64>, Vector3<f64>)> {
        (0..self.num_views())
            .map_while(|i| self.view_columns(block, i))
            .map(|c| {
                let b = c.start;
                (
                    rotvec_to_matrix(&Vector3::new(p[b], p[b + 1], p[b + 2])),
                    Vector3::new(p[b + 3], p[b + 4], p[b + 5]),
                )
            })
            .collect()
    }

    /// The transform of a [`BlockKind::RigidTransform`] block of `p`.
    pub fn transform(&self, p: &[f64], block: Block) -> Iso3 {
        let v = self.full(p);
        let b = self.slots(block).start;
        iso_from_rotvec(
            &Vector3::new(v[b], v[b + 1], v[b + 2]),
            &Vector3::new(v[b + 3], v[b + 4], v[b + 5]),
        )
    }

    /// `out = p (+) dp`: addition, and `R Exp(w)`, `t + v` for the transforms (every
    /// view's instance of a per-view block alike).
    pub fn retract(&self, p: &[f64], dp: &[f64], out: &mut [f64]) {
        for (i, def) in self.blocks.iter().enumerate() {
            let len = def.estimated();
            if len == 0 {
                continue;
            }
            if def.per_view {
                for v in 0..self.num_views() {
                    let b = self.n_global + v * self.per_view_cols + self.col0[i];
                    retract_block(def.kind, b..b + len, p, dp, out);
                }
            } else {
                let b = self.col0[i];
                retract_block(def.kind, b..b + len, p, dp, out);
            }
        }
    }
}

/// The update of one block's columns `r`.
fn retract_block(kind: BlockKind, r: Range<usize>, p: &[f64], dp: &[f64], out: &mut [f64]) {
    match kind {
        BlockKind::Euclidean => {
            for ((o, x), d) in out[r.clone()].iter_mut().zip(&p[r.clone()]).zip(&dp[r]) {
                *o = x + d;
            }
        }
        BlockKind::RigidTransform => {
            let b = r.start;
            let r0 = rotvec_to_matrix(&Vector3::new(p[b], p[b + 1], p[b + 2]));
            let r = r0 * rotvec_to_matrix(&Vector3::new(dp[b], dp[b + 1], dp[b + 2]));
            let rv = matrix_to_rotvec(&r);
            for k in 0..3 {
                out[b + k] = rv[k];
                out[b + 3 + k] = p[b + 3 + k] + dp[b + 3 + k];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calib::joint::{FreeBlocks, JointStart};
    use crate::model::camera::{Camera, DistortionModel, Intrinsics};
    use crate::model::geometry::Plane;

    fn start(model: DistortionModel) -> JointStart {
        let camera = Camera::new(
            768,
            576,
            Intrinsics {
                fu: 1270.0,
                fv: 1320.0,
                u0: 380.0,
                v0: 290.0,
            },
            model,
            [0.05, -0.01, 1e-3, -2e-3, 0.002],
        )
        .unwrap();
        JointStart {
            camera,
            plane: Some(Plane::new(Vector3::new(0.629, -0.0492, 0.7759), 79.87).unwrap()),
            hand_cam: iso_from_rotvec(
                &Vector3::new(-0.3087, 0.2362, 3.0369),
                &Vector3::new(29.19, 5.37, 62.64),
            ),
            base_board: iso_from_rotvec(
                &Vector3::new(0.1, 0.05, -0.4),
                &Vector3::new(450.0, -20.0, 10.0),
            ),
        }
    }

    #[test]
    fn names_and_columns_follow_the_blocks() {
        let s = start(DistortionModel::Radial2);
        let layout = ParamLayout::new(&s, &FreeBlocks::default(), 1.0, &[], PoseNoise::Off, None);
        let names = layout.names();
        let expected = [
            "fu",
            "fv",
            "u0",
            "v0",
            "k1",
            "k2",
            "plane_a",
            "plane_b",
            "plane_d_mm",
            "hand_cam_wx",
            "hand_cam_wy",
            "hand_cam_wz",
            "hand_cam_tx_mm",
            "hand_cam_ty_mm",
            "hand_cam_tz_mm",
            "base_board_wx",
            "base_board_wy",
            "base_board_wz",
            "base_board_tx_mm",
            "base_board_ty_mm",
            "base_board_tz_mm",
        ];
        assert_eq!(names, expected);
        assert_eq!(layout.num_params(), expected.len());
        assert_eq!(layout.slots(Block::Plane), 9..12);
        assert_eq!(layout.slots(Block::BaseBoard), 18..24);
        assert_eq!(
            layout.column(layout.slots(Block::HandCam).start).unwrap(),
            9
        );
        let cols = layout.columns();
        assert_eq!(cols[6], None, "p1 is fixed in radial2");
        assert_eq!(cols[9], Some(6));
    }

    /// Per-view blocks: their columns after the global ones, view after view, their
    /// names by dataset row, the identity at the start, the transforms' update for each
    /// view's instance; none when not estimated.
    #[test]
    fn per_view_blocks_follow_the_global_columns() {
        let s = start(DistortionModel::Radial1);
        let free = FreeBlocks::default();
        let layout = ParamLayout::new(&s, &free, 1.0, &[3, 7], PoseNoise::Robot, None);
        let ng = layout.num_global();
        assert_eq!(ng, 5 + 3 + 12);
        assert_eq!(layout.num_params(), ng + 12);
        assert_eq!(
            layout.view_columns(Block::RobotPose, 1),
            Some(ng + 6..ng + 12)
        );
        assert_eq!(layout.view_columns(Block::RobotPose, 2), None);
        let names = layout.names();
        assert_eq!(names[ng], "view3_robot_wx");
        assert_eq!(names[ng + 11], "view7_robot_tz_mm");
        let p = layout.encode();
        assert!(p[ng..].iter().all(|x| *x == 0.0));
        let d = layout.decode(&p);
        assert_eq!(d.corrections.len(), 2);
        assert_eq!(d.corrections[1].0, Matrix3::identity());
        let a = [iso_from_rotvec(&Vector3::new(0.1, 0.2, 0.3), &Vector3::new(1.0, 2.0, 3.0)); 2];
        for (f, a) in d.flange_poses(&a).iter().zip(&a) {
            assert!((f.to_homogeneous() - a.to_homogeneous()).abs().max() < 1e-15);
        }
        // A step on view 1's correction: R Exp(w), t + v, nothing else moves.
        let mut dp = vec![0.0; p.len()];
        dp[ng + 6] = 0.01;
        dp[ng + 10] = -0.5;
        let mut out = vec![0.0; p.len()];
        layout.retract(&p, &dp, &mut out);
        let d1 = layout.decode(&out);
        assert!(
            (d1.corrections[1].0 - rotvec_to_matrix(&Vector3::new(0.01, 0.0, 0.0)))
                .abs()
                .max()
                < 1e-15
        );
        assert_eq!(d1.corrections[1].1, Vector3::new(0.0, -0.5, 0.0));
        assert_eq!(d1.corrections[0].0, Matrix3::identity());
        assert!(out[..ng]
            .iter()
            .zip(&p[..ng])
            .all(|(a, b)| (a - b).abs() < 1e-12));
        // A_i D_i.
        let f = d1.flange_poses(&a);
        let expect =
            a[1] * iso_from_rotvec(&Vector3::new(0.01, 0.0, 0.0), &Vector3::new(0.0, -0.5, 0.0));
        assert!(
            (f[1].to_homogeneous() - expect.to_homogeneous())
                .abs()
                .max()
                < 1e-12
        );
        // With the image part: its six after each view's correction, plain numbers.
        let both = ParamLayout::new(&s, &free, 1.0, &[3, 7], PoseNoise::RobotAndImage, None);
        assert_eq!(both.num_params(), ng + 24);
        assert_eq!(both.per_view_len(), 12);
        assert_eq!(
            both.view_columns(Block::RobotPose, 1),
            Some(ng + 12..ng + 18)
        );
        assert_eq!(
            both.view_columns(Block::ImagePose, 1),
            Some(ng + 18..ng + 24)
        );
        let names = both.names();
        assert_eq!(names[ng + 6], "view3_image_wx");
        assert_eq!(names[ng + 23], "view7_image_tz_mm");
        let mut dp = vec![0.0; both.num_params()];
        dp[ng + 19] = 0.25;
        let p = both.encode();
        let mut out = vec![0.0; p.len()];
        both.retract(&p, &dp, &mut out);
        let d = both.decode(&out);
        assert_eq!(
            d.image_pose,
            vec![[0.0; 6], [0.0, 0.25, 0.0, 0.0, 0.0, 0.0]]
        );
        assert_eq!(d.corrections[1].0, Matrix3::identity());
        let rigid = ParamLayout::new(&s, &free, 1.0, &[3, 7], PoseNoise::Off, None);
        assert_eq!(rigid.num_params(), ng);
        assert!(rigid.decode(&rigid.encode()).corrections.is_empty());
        assert!(!rigid.per_view_free(Block::RobotPose));
    }

    #[test]
    fn encode_decode_and_retract_round_trip() {
        let s = start(DistortionModel::OpenCv5);
        let layout = ParamLayout::new(&s, &FreeBlocks::default(), 1.0, &[], PoseNoise::Off, None);
        let p = layout.encode();
        assert_eq!(p.len(), layout.num_params());
        let d = layout.decode(&p);
        assert_eq!(d.cam, s.camera.params());
        let plane = s.plane.unwrap();
        assert!((d.plane_n - plane.normal).norm() < 1e-15);
        assert_eq!(d.plane_d, plane.d);
        assert_eq!(d.scale, 1.0);
        let x = layout.transform(&p, Block::HandCam);
        assert!(
            (x.to_homogeneous() - s.hand_cam.to_homogeneous())
                .abs()
                .max()
                < 1e-12
        );
        // A rotation step is applied on the right: R Exp(w).
        let mut dp = vec![0.0; p.len()];
        let b = layout.column(layout.slots(Block::BaseBoard).start).unwrap();
        dp[b + 2] = 0.01;
        dp[b + 4] = 2.0;
        let mut out = vec![0.0; p.len()];
        layout.retract(&p, &dp, &mut out);
        let z0 = layout.transform(&p, Block::BaseBoard);
        let z1 = layout.transform(&out, Block::BaseBoard);
        let expect = z0.rotation.to_rotation_matrix().into_inner()
            * rotvec_to_matrix(&Vector3::new(0.0, 0.0, 0.01));
        let got = z1.rotation.to_rotation_matrix().into_inner();
        assert!((got - expect).abs().max() < 1e-12);
        assert!((z1.translation.vector.y - z0.translation.vector.y - 2.0).abs() < 1e-12);
        // Additive blocks are unchanged by a zero step; a transform's rotation vector
        // goes through its matrix (round-off only).
        let x = layout.column(layout.slots(Block::HandCam).start).unwrap();
        assert_eq!(&out[..x], &p[..x]);
        assert!(out[x..b]
            .iter()
            .zip(&p[x..b])
            .all(|(a, c)| (a - c).abs() < 1e-12));
    }
}
