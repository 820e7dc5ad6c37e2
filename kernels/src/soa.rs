//! Structure-of-arrays vector fields: three component slices, one entry per
//! particle (positions, velocities, accelerations, fluxes), and the step
//! arena's helpers that allocate them zeroed.

use bumpalo::Bump;

/// A vector field read as three component slices of equal length.
#[derive(Clone, Copy)]
pub struct Vel<'a> {
    pub x: &'a [f32],
    pub y: &'a [f32],
    pub z: &'a [f32],
}

impl<'a> Vel<'a> {
    /// The entries `r` of each component.
    pub fn range(self, r: std::ops::Range<usize>) -> Vel<'a> {
        Vel { x: &self.x[r.clone()], y: &self.y[r.clone()], z: &self.z[r] }
    }

    /// Number of entries.
    pub fn len(&self) -> usize {
        self.x.len()
    }

    /// Whether there are no entries.
    pub fn is_empty(&self) -> bool {
        self.x.is_empty()
    }
}

/// A vector field written as three mutable component slices.
pub struct VelMut<'a> {
    pub x: &'a mut [f32],
    pub y: &'a mut [f32],
    pub z: &'a mut [f32],
}

impl<'a> VelMut<'a> {
    /// The same arrays, borrowed again for a shorter time.
    pub fn reborrow(&mut self) -> VelMut<'_> {
        VelMut { x: &mut *self.x, y: &mut *self.y, z: &mut *self.z }
    }

    /// The same arrays, read.
    pub fn view(&self) -> Vel<'_> {
        Vel { x: &*self.x, y: &*self.y, z: &*self.z }
    }

    /// The same arrays, read for as long as they were lent.
    pub fn into_view(self) -> Vel<'a> {
        Vel { x: self.x, y: self.y, z: self.z }
    }

    /// The entries `r` of each component.
    pub fn range(&mut self, r: std::ops::Range<usize>) -> VelMut<'_> {
        VelMut { x: &mut self.x[r.clone()], y: &mut self.y[r.clone()], z: &mut self.z[r] }
    }
}

/// `n` zeros from the step arena.
pub fn zeros(arena: &Bump, n: usize) -> &mut [f32] {
    arena.alloc_slice_fill_copy(n, 0.0f32)
}

/// A zero vector field of `n` entries from the step arena.
pub fn zeros3(arena: &Bump, n: usize) -> VelMut<'_> {
    VelMut { x: zeros(arena, n), y: zeros(arena, n), z: zeros(arena, n) }
}
