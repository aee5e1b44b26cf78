//! How the sensor was held while a calibration's views were taken: on a robot's flange
//! (hand-eye `X` and robot-world `Z` estimated) or on the bench (no robot, no poses).

/// How the sensor was held (calibration.json: a robot calibration has `hand_cam` and
/// `base_board`, a bench calibration neither and `"bench": true`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Mount {
    /// On a robot's flange: the calibration's `hand_cam` (X) and `base_board` (Z) were
    /// estimated, with `robot` the DH table used when rig.json has one.
    #[default]
    Robot,
    /// On the bench (a dataset without poses): camera and laser plane only; the
    /// calibration's `hand_cam` and `base_board` hold the identity, its file has neither
    /// (nor `robot`) and says `"bench": true`.
    Bench,
}
