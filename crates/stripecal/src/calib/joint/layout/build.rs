//! How a [`ParamLayout`] is built: the blocks a camera, the bench or a profiler
//! registers, their estimated values, and every slot's starting value.

use nalgebra::Vector3;

use super::{Block, BlockDef, BlockKind, ParamLayout, PlaneChart, PoseNoise, SphereStart, SLOTS};
use crate::calib::joint::robot::RobotBlock;
use crate::calib::joint::{FreeBlocks, JointOptions, JointStart};
use crate::model::camera::{MAX_DISTORTION, PARAM_NAMES};
use crate::model::geometry::{iso_to_rotvec, Iso3};

/// What [`ParamLayout::build`] registers: each block's estimated values and the start.
struct BuildSpec<'a> {
    /// The camera's nine slots: names (the model's parameters, then unused slots) and
    /// which are estimated.
    cam_names: Vec<String>,
    cam_free: Vec<bool>,
    plane_free: bool,
    free: FreeBlocks,
    robot_noise: bool,
    image_pose: bool,
    robot: Option<RobotBlock>,
    board_poses: Option<&'a [Iso3]>,
    sphere: Option<SphereStart>,
    /// The slots' values at the start, and the plane's normal there.
    base: [f64; SLOTS],
    n0: Vector3<f64>,
}

impl ParamLayout {
    /// The layout of an adjustment with options `opts` over the views `used` (dataset
    /// rows): [`Self::new`] with their board scale and robot-pose noise.
    pub fn of(
        start: &JointStart,
        free: &FreeBlocks,
        opts: &JointOptions,
        used: &[usize],
        robot: Option<RobotBlock>,
    ) -> ParamLayout {
        ParamLayout::new(
            start,
            free,
            opts.board_scale,
            used,
            PoseNoise::of(opts),
            robot,
        )
    }

    /// The layout around `start`: the camera's four intrinsics and its model's free
    /// distortion coefficients, the laser plane charted around the starting normal, `X`,
    /// `Z` and the board scale (held at `scale` unless estimated), each estimated as
    /// `free` says; per view of `view_ids` (dataset rows) a robot-pose correction,
    /// estimated when `noise` is not [`PoseNoise::Off`], and its image-pose part with
    /// [`PoseNoise::RobotAndImage`]. Without a starting plane the plane block is held
    /// (it has no observations then).
    pub fn new(
        start: &JointStart,
        free: &FreeBlocks,
        scale: f64,
        view_ids: &[usize],
        noise: PoseNoise,
        robot: Option<RobotBlock>,
    ) -> ParamLayout {
        let spec = BuildSpec::camera(start, free, scale, noise, robot, None);
        Self::build(spec, view_ids)
    }

    /// The bench's layout ([`super::super::bench`]): the camera and the laser plane as `free`
    /// says, `X`, `Z` and the board scale held (at the identity and 1), and per view of
    /// `view_ids` its board pose, free, starting at `board_poses` (`T_cam_board`).
    pub fn bench(
        start: &JointStart,
        free: &FreeBlocks,
        view_ids: &[usize],
        board_poses: &[Iso3],
    ) -> ParamLayout {
        let free = FreeBlocks {
            hand_cam: false,
            base_board: false,
            board_scale: false,
            ..*free
        };
        let spec = BuildSpec::camera(start, &free, 1.0, PoseNoise::Off, None, Some(board_poses));
        Self::build(spec, view_ids)
    }

    /// A profiler's layout ([`super::super::profile`]): `X = T_hand_sensor` (estimated when
    /// `hand_free`), the sphere's centre and (when `sphere.diameter_free`) its diameter,
    /// the robot block; every camera block held.
    pub fn profiler(
        hand_sensor: &Iso3,
        hand_free: bool,
        sphere: SphereStart,
        view_ids: &[usize],
        robot: Option<RobotBlock>,
    ) -> ParamLayout {
        let mut base = [0.0; SLOTS];
        let (rv, tr) = iso_to_rotvec(hand_sensor);
        // the camera's slots are never read; the board scale is 1
        base[9 + 3..9 + 3 + 6].copy_from_slice(&[rv.x, rv.y, rv.z, tr.x, tr.y, tr.z]);
        base[SLOTS - 1] = 1.0;
        let spec = BuildSpec {
            cam_names: PARAM_NAMES.iter().map(|s| s.to_string()).collect(),
            cam_free: vec![false; 9],
            plane_free: false,
            free: FreeBlocks {
                camera: false,
                laser_plane: false,
                hand_cam: hand_free,
                base_board: false,
                board_scale: false,
            },
            robot_noise: false,
            image_pose: false,
            robot,
            board_poses: None,
            sphere: Some(sphere),
            base,
            n0: Vector3::z(),
        };
        let layout = Self::build(spec, view_ids);
        debug_assert_eq!(layout.slots(Block::HandCam).start, 12);
        layout
    }

    fn build(spec: BuildSpec<'_>, view_ids: &[usize]) -> ParamLayout {
        let BuildSpec {
            cam_names,
            cam_free,
            plane_free,
            free,
            robot_noise,
            image_pose,
            robot,
            board_poses,
            sphere,
            base,
            n0,
        } = spec;
        let blocks = vec![
            BlockDef {
                block: Block::Camera,
                kind: BlockKind::Euclidean,
                names: cam_names,
                free: cam_free,
                per_view: false,
                slotless: false,
            },
            BlockDef::euclidean(
                Block::Plane,
                &["plane_a", "plane_b", "plane_d_mm"],
                vec![plane_free; 3],
            ),
            BlockDef::transform(Block::HandCam, "hand_cam", free.hand_cam),
            BlockDef::transform(Block::BaseBoard, "base_board", free.base_board),
            BlockDef::euclidean(Block::BoardScale, &["board_scale"], vec![free.board_scale]),
            BlockDef::transform(Block::RobotPose, "robot", robot_noise).per_view(),
            BlockDef::euclidean(
                Block::ImagePose,
                &[
                    "image_wx",
                    "image_wy",
                    "image_wz",
                    "image_tx_mm",
                    "image_ty_mm",
                    "image_tz_mm",
                ],
                vec![robot_noise && image_pose; 6],
            )
            .per_view(),
            BlockDef::transform(Block::BoardPose, "board", board_poses.is_some()).per_view(),
            BlockDef::euclidean(
                Block::SphereCentre,
                &["sphere_cx_mm", "sphere_cy_mm", "sphere_cz_mm"],
                vec![sphere.is_some(); 3],
            )
            .slotless(),
            BlockDef::euclidean(
                Block::SphereDiameter,
                &["sphere_diameter_mm"],
                vec![sphere.is_some_and(|s| s.diameter_free)],
            )
            .slotless(),
            BlockDef {
                block: Block::Robot,
                kind: BlockKind::Euclidean,
                names: robot
                    .iter()
                    .flat_map(|r| r.params.iter().map(|p| p.name()))
                    .collect(),
                free: robot
                    .as_ref()
                    .map_or(vec![], |r| vec![true; r.params.len()]),
                per_view: false,
                slotless: true,
            },
        ];
        let (mut slot0, mut col0, mut col_of_slot) = (Vec::new(), Vec::new(), Vec::new());
        let (mut col, mut view_col) = (0, 0);
        for b in &blocks {
            slot0.push(col_of_slot.len());
            if b.per_view {
                col0.push(view_col);
                view_col += b.estimated();
                continue;
            }
            if b.slotless {
                col0.push(col);
                col += b.estimated();
                continue;
            }
            col0.push(col);
            for &f in &b.free {
                col_of_slot.push(f.then_some(col));
                col += usize::from(f);
            }
        }
        debug_assert_eq!(col_of_slot.len(), SLOTS);
        let mut view_base = vec![0.0; view_ids.len() * view_col];
        if let Some(poses) = board_poses {
            let c = col0[blocks
                .iter()
                .position(|b| b.block == Block::BoardPose)
                .unwrap_or(0)];
            for (v, t) in poses.iter().enumerate().take(view_ids.len()) {
                let (rv, tr) = iso_to_rotvec(t);
                let b = v * view_col + c;
                view_base[b..b + 6].copy_from_slice(&[rv.x, rv.y, rv.z, tr.x, tr.y, tr.z]);
            }
        }
        ParamLayout {
            view_base,
            blocks,
            slot0,
            col0,
            col_of_slot,
            base,
            n_global: col,
            view_ids: view_ids.to_vec(),
            per_view_cols: view_col,
            chart: PlaneChart::around(n0),
            robot,
            sphere,
        }
    }
}

impl BuildSpec<'_> {
    /// A camera's blocks: the camera's four intrinsics and its model's free distortion
    /// coefficients, the plane (held without a starting plane), `X`, `Z` and the board
    /// scale as `free` says.
    fn camera<'a>(
        start: &JointStart,
        free: &FreeBlocks,
        scale: f64,
        noise: PoseNoise,
        robot: Option<RobotBlock>,
        board_poses: Option<&'a [Iso3]>,
    ) -> BuildSpec<'a> {
        // the model's parameters in the first slots (brown5: all nine), the rest held
        let model = start.camera.projection.model();
        let coefficients = model.free_coefficients(start.camera.model);
        let mut cam_free = vec![free.camera; 4];
        cam_free.extend(
            (0..MAX_DISTORTION)
                .map(|i| free.camera && coefficients.get(i).copied().unwrap_or(false)),
        );
        let mut cam_names: Vec<String> =
            model.param_names().iter().map(|s| s.to_string()).collect();
        cam_names.extend((cam_names.len()..PARAM_NAMES.len()).map(|i| format!("unused_{i}")));
        BuildSpec {
            cam_names,
            cam_free,
            plane_free: free.laser_plane && start.plane.is_some(),
            free: *free,
            robot_noise: noise != PoseNoise::Off,
            image_pose: noise == PoseNoise::RobotAndImage,
            robot,
            board_poses,
            sphere: None,
            base: slot_values(start, scale),
            n0: start.plane.map_or(Vector3::z(), |p| p.normal),
        }
    }
}

/// Every slot's value at `start`: the camera's parameters (slots 0..9), the plane's
/// chart coordinates (0, 0) and offset (9..12), `X` (12..18) and `Z` (18..24) as
/// rotation vector and translation, the board scale (24).
fn slot_values(start: &JointStart, scale: f64) -> [f64; SLOTS] {
    let mut v = [0.0; SLOTS];
    v[0..9].copy_from_slice(&start.camera.params());
    v[11] = start.plane.map_or(0.0, |p| p.d);
    for (s, t) in [(12, &start.hand_cam), (18, &start.base_board)] {
        let (rv, tr) = iso_to_rotvec(t);
        v[s..s + 6].copy_from_slice(&[rv.x, rv.y, rv.z, tr.x, tr.y, tr.z]);
    }
    v[24] = scale;
    v
}
