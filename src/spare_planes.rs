//! Planes of frames gone by, kept for the frames after: a plane the
//! encoder needs every frame (a search's half-pel planes, the deblocking
//! trial's copy) would otherwise be allocated, zeroed and faulted in each
//! time. One store for every thread: at two threads a frame thread drops
//! what the thread starting the next frame takes. A plane taken holds
//! whatever it held: its users write before they read.

use std::sync::{Mutex, MutexGuard, PoisonError};

use crate::codec::Plane;

/// A store of spare planes, taken by size and border.
struct PlaneStore(Mutex<Vec<Plane>>);

impl PlaneStore {
    const fn new() -> PlaneStore {
        PlaneStore(Mutex::new(Vec::new()))
    }

    /// The spare planes (a panic while they were held leaves them whole).
    fn planes(&self) -> MutexGuard<'_, Vec<Plane>> {
        self.0.lock().unwrap_or_else(PoisonError::into_inner)
    }

    fn take(&self, w: usize, h: usize, pad: usize) -> Option<Plane> {
        let reused = {
            let mut s = self.planes();
            s.iter()
                .position(|p| (p.width(), p.height(), p.pad()) == (w, h, pad))
                .map(|i| s.swap_remove(i))
        };
        reused.or_else(|| Plane::with_padding(w, h, pad).ok())
    }

    fn give_back(&self, planes: impl IntoIterator<Item = Plane>, keep: usize) {
        let mut s = self.planes();
        s.extend(planes);
        let excess = s.len().saturating_sub(keep);
        let gone: Vec<Plane> = s.drain(..excess).collect();
        // Freed once the others can take theirs.
        drop(s);
        drop(gone);
    }
}

static SPARE: PlaneStore = PlaneStore::new();

/// A plane of this size and border from the spares, or a new one (none
/// for a size no plane can have).
pub(crate) fn take(w: usize, h: usize, pad: usize) -> Option<Plane> {
    SPARE.take(w, h, pad)
}

/// `planes` back among the spares. Enough are kept for two frames in
/// flight (three half-pel planes and a trial's copy each), or two sizes
/// in turn, for each thread of the pool (searches running side by side,
/// as `mocomp rd`'s encodes do); older ones go.
pub(crate) fn give_back(planes: impl IntoIterator<Item = Plane>) {
    SPARE.give_back(planes, 8 * rayon::current_num_threads().max(1));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_plane_given_back_is_taken_again_by_its_size_and_the_oldest_go() {
        let store = PlaneStore::new();
        let (w, h, pad) = (48, 40, 7);
        let mut plane = store.take(w, h, pad).expect("a plane");
        plane.set(3, 4, 99);
        store.give_back([plane], 2);
        // Another size is a new plane.
        let other = store.take(w, h + 8, pad).expect("a plane");
        assert_eq!((other.height(), other.get(3, 4)), (h + 8, 0));
        let again = store.take(w, h, pad).expect("the plane given back");
        assert_eq!(again.get(3, 4), 99, "the same plane, its content as left");
        // Beyond `keep`, the oldest go.
        store.give_back([again, other], 1);
        assert_eq!(store.take(w, h, pad).expect("a plane").get(3, 4), 0);
    }
}
