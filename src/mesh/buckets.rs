//! A uniform grid of buckets for geometric searches (point location, boundary checks).

use super::{max2, min2};

/// A uniform grid of buckets over a bounding box, holding item indices by box overlap.
pub(crate) struct Buckets {
    lo: [f64; 2],
    cell: [f64; 2],
    dims: [usize; 2],
    start: Vec<usize>,
    items: Vec<usize>,
}

impl Buckets {
    /// Buckets for points, about one per bucket.
    pub(crate) fn new(points: impl Iterator<Item = [f64; 2]> + Clone, count: usize) -> Self {
        Self::from_boxes(points.map(|p| (p, p)), count)
    }

    pub(crate) fn from_boxes(
        boxes: impl Iterator<Item = ([f64; 2], [f64; 2])> + Clone,
        count: usize,
    ) -> Self {
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for (a, b) in boxes.clone() {
            lo = min2(lo, a);
            hi = max2(hi, b);
        }
        let side = (count.max(1) as f64).sqrt().ceil() as usize;
        let dims = [side.max(1), side.max(1)];
        let cell = [
            ((hi[0] - lo[0]) / dims[0] as f64).max(f64::MIN_POSITIVE),
            ((hi[1] - lo[1]) / dims[1] as f64).max(f64::MIN_POSITIVE),
        ];
        let mut grid = Buckets {
            lo,
            cell,
            dims,
            start: vec![0; dims[0] * dims[1] + 1],
            items: Vec::new(),
        };
        for (a, b) in boxes.clone() {
            for c in grid.cells(a, b) {
                grid.start[c + 1] += 1;
            }
        }
        for c in 0..dims[0] * dims[1] {
            grid.start[c + 1] += grid.start[c];
        }
        let mut fill = grid.start.clone();
        grid.items = vec![0; grid.start[dims[0] * dims[1]]];
        for (i, (a, b)) in boxes.enumerate() {
            for c in grid.cells(a, b) {
                grid.items[fill[c]] = i;
                fill[c] += 1;
            }
        }
        grid
    }

    fn index(&self, p: [f64; 2], k: usize) -> usize {
        (((p[k] - self.lo[k]) / self.cell[k]).floor().max(0.0) as usize).min(self.dims[k] - 1)
    }

    fn cells(&self, a: [f64; 2], b: [f64; 2]) -> impl Iterator<Item = usize> {
        let (i0, i1, j0, j1) = (
            self.index(a, 0),
            self.index(b, 0),
            self.index(a, 1),
            self.index(b, 1),
        );
        let nx = self.dims[0];
        (j0..=j1).flat_map(move |j| (i0..=i1).map(move |i| j * nx + i))
    }

    /// The items in the bucket of p and the eight around it.
    pub(crate) fn around(&self, p: [f64; 2]) -> impl Iterator<Item = usize> + '_ {
        let (a, b) = (
            [p[0] - self.cell[0], p[1] - self.cell[1]],
            [p[0] + self.cell[0], p[1] + self.cell[1]],
        );
        self.near_box(a, b)
    }

    pub(crate) fn near_box(&self, a: [f64; 2], b: [f64; 2]) -> impl Iterator<Item = usize> + '_ {
        self.cells(a, b)
            .flat_map(move |c| self.items[self.start[c]..self.start[c + 1]].iter().copied())
    }
}
