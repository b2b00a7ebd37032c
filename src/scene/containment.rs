//! [`Mesh::contains`] for many points: the same parity ray and the same
//! crossing test, with the mesh's triangles binned by their shadow along
//! the ray on a grid, so that a point tests only the triangles its ray
//! may cross instead of all of them.

use glam::{DVec2, DVec3};

use super::{ray_crosses, Mesh, CONTAINMENT_RAY};

/// A closed mesh's triangles binned for [`Mesh::contains`] queries.
pub struct ContainmentGrid<'a> {
    mesh: &'a Mesh,
    /// Two unit vectors perpendicular to the ray: a point's shadow is its
    /// coordinates along them.
    u: DVec3,
    v: DVec3,
    /// The grid's lower corner, cell size and cells per side.
    lo: DVec2,
    cell: DVec2,
    side: usize,
    /// Per cell, its triangles: `tris[starts[c]..starts[c + 1]]`.
    starts: Vec<u32>,
    tris: Vec<u32>,
    /// Triangles nearly parallel to the ray, tested for every point: their
    /// crossing test divides by a tiny determinant, so its rounding could
    /// reach past any padding of their shadow.
    always: Vec<u32>,
}

/// Below this ratio of `|det|` to `|e1|·|e2|` a triangle counts as nearly
/// parallel to the ray ([`ContainmentGrid::always`]).
const PARALLEL: f64 = 1e-6;

impl<'a> ContainmentGrid<'a> {
    /// Bins `mesh`'s triangles (an open mesh contains nothing: every
    /// query is false, as for [`Mesh::contains`]).
    pub fn new(mesh: &'a Mesh) -> Self {
        let dir = CONTAINMENT_RAY;
        let u = dir.normalize().any_orthonormal_vector();
        let v = dir.normalize().cross(u);
        let shadow = |p: DVec3| DVec2::new(p.dot(u), p.dot(v));
        let n = if mesh.closed { mesh.indices.len() } else { 0 };
        // Padding of every shadow: far above the crossing test's rounding
        // for a triangle that is not nearly parallel to the ray (about
        // 1e-9 of the coordinates' size; see `bin`), far below any cell.
        let scale = match mesh.bounds() {
            Some((blo, bhi)) if n > 0 => {
                (bhi - blo).length() + blo.abs().max(bhi.abs()).max_element()
            }
            _ => 0.0,
        };
        let pad = 1e-6 * scale;
        let mut always = Vec::new();
        let mut boxes = Vec::with_capacity(n);
        for t in 0..n {
            let [a, b, c] = mesh.triangle(t);
            let (e1, e2) = (b - a, c - a);
            let det = e1.dot(dir.cross(e2));
            if det.abs() <= PARALLEL * e1.length() * e2.length() * dir.length() || !det.is_finite()
            {
                always.push(t as u32);
                continue;
            }
            let (sa, sb, sc) = (shadow(a), shadow(b), shadow(c));
            let lo = sa.min(sb).min(sc) - pad;
            let hi = sa.max(sb).max(sc) + pad;
            boxes.push((t as u32, lo, hi));
        }
        let (mut lo, mut hi) = (DVec2::INFINITY, DVec2::NEG_INFINITY);
        for (_, l, h) in &boxes {
            lo = lo.min(*l);
            hi = hi.max(*h);
        }
        // About one triangle per cell.
        let side = ((boxes.len() as f64).sqrt().ceil() as usize).clamp(1, 1024);
        let cell = if boxes.is_empty() {
            DVec2::ONE
        } else {
            ((hi - lo) / side as f64).max(DVec2::splat(f64::MIN_POSITIVE))
        };
        let mut grid = ContainmentGrid {
            mesh,
            u,
            v,
            lo,
            cell,
            side,
            starts: vec![0; side * side + 1],
            tris: Vec::new(),
            always,
        };
        // Counts, exclusive scan, scatter.
        let ranges: Vec<_> = boxes
            .iter()
            .map(|&(t, l, h)| (t, grid.cell_of(l), grid.cell_of(h)))
            .collect();
        for &(_, (x0, y0), (x1, y1)) in &ranges {
            for y in y0..=y1 {
                for x in x0..=x1 {
                    grid.starts[y * side + x + 1] += 1;
                }
            }
        }
        for c in 0..side * side {
            grid.starts[c + 1] += grid.starts[c];
        }
        let mut next = grid.starts.clone();
        grid.tris = vec![0; grid.starts[side * side] as usize];
        for &(t, (x0, y0), (x1, y1)) in &ranges {
            for y in y0..=y1 {
                for x in x0..=x1 {
                    let c = y * side + x;
                    grid.tris[next[c] as usize] = t;
                    next[c] += 1;
                }
            }
        }
        grid
    }

    /// The cell whose column and row hold shadow coordinates `s`, clamped
    /// to the grid (monotonic in each coordinate, so a box's cells are the
    /// range between its corners' cells).
    fn cell_of(&self, s: DVec2) -> (usize, usize) {
        let f = ((s - self.lo) / self.cell).floor();
        let clamp = |x: f64| (x.max(0.0) as usize).min(self.side - 1);
        (clamp(f.x), clamp(f.y))
    }

    /// Whether `p` lies inside the mesh: exactly [`Mesh::contains`]`(p)`.
    ///
    /// A triangle that the ray from `p` crosses has `p`'s shadow inside
    /// its own, up to the crossing test's rounding: at most a few ulps of
    /// `|p - a|·|e1|·|e2| / |det|`, under 1e-9 of the coordinates' size
    /// when `|det|` is at least 1e-6 of `|e1|·|e2|` (the nearly
    /// parallel rest is tested for every point). The padding is 1e-6 of
    /// that size, so every such triangle is binned in `p`'s cell.
    pub fn contains(&self, p: DVec3) -> bool {
        if !self.mesh.closed {
            return false;
        }
        let crosses = |t: &u32| ray_crosses(p, CONTAINMENT_RAY, self.mesh.triangle(*t as usize));
        let mut n = self.always.iter().filter(|t| crosses(t)).count();
        let s = DVec2::new(p.dot(self.u), p.dot(self.v));
        let hi = self.lo + self.cell * self.side as f64;
        if s.cmpge(self.lo).all() && s.cmple(hi).all() {
            let (x, y) = self.cell_of(s);
            let c = y * self.side + x;
            let cell = &self.tris[self.starts[c] as usize..self.starts[c + 1] as usize];
            n += cell.iter().filter(|t| crosses(t)).count();
        }
        n % 2 == 1
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::builtin;

    /// Every closed mesh of the built-in scenes (spheres, boxes, torus
    /// knots, the hairball's strands where closed), queried at random
    /// points around it and at every vertex and edge midpoint (rays
    /// through edges and corners): the grid's answer is the brute force's.
    #[test]
    fn the_grid_answers_as_every_triangle_does() {
        let mut rng = builtin::Rng(0x9e37_79b9_7f4a_7c15);
        let mut next = move || rng.f64();
        let mut meshes = 0;
        let (mut inside, mut outside) = (0, 0);
        for name in builtin::NAMES {
            let desc = crate::scene::file::load(&format!("builtin:{name}")).unwrap();
            for mesh in desc.scene.meshes.iter().filter(|m| m.closed).take(3) {
                meshes += 1;
                let grid = ContainmentGrid::new(mesh);
                let (lo, hi) = mesh.bounds().unwrap();
                let mut points: Vec<DVec3> = (0..400)
                    .map(|_| {
                        let t = DVec3::new(next(), next(), next()) * 1.2 - 0.1;
                        lo + (hi - lo) * t
                    })
                    .collect();
                for t in 0..mesh.indices.len().min(300) {
                    let [a, b, c] = mesh.triangle(t);
                    points.extend([a, (a + b) * 0.5, (b + c) * 0.5, (a + b + c) / 3.0]);
                }
                for p in points {
                    let want = mesh.contains(p);
                    assert_eq!(grid.contains(p), want, "{name}: {} at {p}", mesh.name);
                    if want {
                        inside += 1;
                    } else {
                        outside += 1;
                    }
                }
            }
        }
        assert!(meshes >= 3, "{meshes} closed meshes");
        assert!(
            inside > 100 && outside > 100,
            "{inside} inside, {outside} outside"
        );
    }

    #[test]
    fn open_and_empty_meshes_contain_nothing() {
        let open = Mesh::new(
            "square",
            vec![DVec3::ZERO, DVec3::X, DVec3::new(1.0, 1.0, 0.0), DVec3::Y],
            vec![[0, 1, 2], [0, 2, 3]],
        );
        assert!(!open.closed);
        let empty = Mesh::new("empty", Vec::new(), Vec::new());
        for mesh in [&open, &empty] {
            let grid = ContainmentGrid::new(mesh);
            assert!(!grid.contains(DVec3::new(0.5, 0.5, -1.0)));
            assert!(!grid.contains(DVec3::ZERO));
        }
    }
}
