//! Consensus over views: which views agree with each other through `A_i X = Z B_i`
//! (`A_i = T_base_hand`, `B_i = T_board_cam`), before any adjustment.
//!
//! One place for the two questions the robot poses answer about the images
//! (DECISIONS 2):
//! - [`labelling`]: which labelling of a symmetric board each view's image shows
//!   ([`choose`]), from pairwise screw invariants that need no estimate of `X` or `Z`;
//! - [`pairing`]: which views' robot poses do not fit their images (a swapped pair, a
//!   mistyped joint reading, the whole pose column shifted by a row), by least median
//!   of squares over minimal subsets of views ([`find_consensus`]) and, when too few
//!   views agree, by testing shifted pairings ([`find_shift`]).

pub mod labelling;
pub mod pairing;

pub use labelling::{choose, symmetry_motion, Candidates, Decision};
pub use pairing::{
    find_break, find_consensus, find_shift, Break, Consensus, PairingOptions, Shift,
};
