//! Integer lattice coordinates (a grid site's `(i, j)`, a pixel's `(x, y)`) and the maps
//! and sets keyed by them, with a hash made for small integers.

use std::collections::{HashMap, HashSet};
use std::hash::{BuildHasherDefault, Hasher};

/// Integer lattice coordinates `(i, j)` (also a pixel's `(x, y)`).
pub(crate) type Coord = (i32, i32);

/// A map keyed by lattice sites or pixels, hashed by [`CoordHasher`].
pub(crate) type CoordMap<V> = HashMap<Coord, V, BuildHasherDefault<CoordHasher>>;

/// A set of lattice sites or pixels, hashed by [`CoordHasher`].
pub(crate) type CoordSet = HashSet<Coord, BuildHasherDefault<CoordHasher>>;

/// The hash of small integers: each one xor-ed into the rotated state and multiplied by
/// an odd constant (a multiply-rotate mix, the scheme of rustc's FxHash). The standard
/// library's SipHash guards against keys chosen to collide, which the detectors' own
/// sites and pixels are not, at several times the cost. The maps' iteration order does
/// not reach any result (with SipHash it was random per process).
#[derive(Default, Clone, Copy)]
pub(crate) struct CoordHasher(u64);

impl Hasher for CoordHasher {
    #[inline]
    fn finish(&self) -> u64 {
        self.0
    }
    #[inline]
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(u64::from(b));
        }
    }
    #[inline]
    fn write_i32(&mut self, i: i32) {
        self.write_u64(u64::from(i as u32));
    }
    #[inline]
    fn write_u64(&mut self, i: u64) {
        self.0 = (self.0.rotate_left(5) ^ i).wrapping_mul(0x517c_c1b7_2722_0a95);
    }
}
