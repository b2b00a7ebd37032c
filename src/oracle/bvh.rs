//! A binned-SAH bounding volume hierarchy over origin-relative `f64`
//! triangles, flattened into 32-byte nodes, with iterative nearest-hit and
//! any-hit traversal.

use super::intersect::{Hit, Ray};

/// Number of SAH bins per axis.
const BINS: usize = 16;
/// Leaves never hold more triangles than this unless their centroids coincide
/// and the depth limit forces median splits (which still halve them).
const MAX_LEAF: usize = 8;
/// Cost of visiting a node relative to one triangle test.
const TRAVERSAL_COST: f64 = 1.0;
/// Below this depth splits are chosen by the SAH, from it by object median,
/// which bounds the tree depth by `SAH_DEPTH + 32`.
const SAH_DEPTH: usize = 48;
/// Traversal stack size; larger than any possible tree depth.
const STACK: usize = 96;

/// A flattened node: conservative `f32` bounds, and either two children at
/// `first` and `first + 1` (`count == 0`) or `count` triangles from `first`.
#[derive(Clone, Copy, Debug, Default)]
#[repr(C)]
struct Node {
    bounds: [[f32; 3]; 2],
    first: u32,
    count: u32,
}

/// The hierarchy and its triangles in leaf order.
#[derive(Default)]
pub(crate) struct Bvh {
    nodes: Vec<Node>,
    /// Vertices relative to the oracle's origin, in leaf order.
    tris: Vec<[[f64; 3]; 3]>,
    /// Global triangle id of each entry of `tris`.
    ids: Vec<u32>,
    depth: usize,
}

/// Nearest hit of a ray.
#[derive(Clone, Copy, Debug)]
pub(crate) struct NearestHit {
    pub hit: Hit,
    /// Index into the leaf-ordered triangles.
    pub index: u32,
}

#[derive(Clone, Copy)]
struct Aabb {
    lo: [f64; 3],
    hi: [f64; 3],
}

impl Aabb {
    const EMPTY: Aabb = Aabb {
        lo: [f64::INFINITY; 3],
        hi: [f64::NEG_INFINITY; 3],
    };

    fn grow(&mut self, o: &Aabb) {
        for k in 0..3 {
            self.lo[k] = self.lo[k].min(o.lo[k]);
            self.hi[k] = self.hi[k].max(o.hi[k]);
        }
    }

    fn grow_point(&mut self, p: &[f64; 3]) {
        self.grow(&Aabb { lo: *p, hi: *p });
    }

    /// Half the surface area (0 for an empty box).
    fn half_area(&self) -> f64 {
        let d = [
            self.hi[0] - self.lo[0],
            self.hi[1] - self.lo[1],
            self.hi[2] - self.lo[2],
        ];
        if d[0] < 0.0 {
            return 0.0;
        }
        d[0] * d[1] + d[1] * d[2] + d[2] * d[0]
    }

    /// Outward-rounded `f32` bounds.
    fn to_f32(self) -> [[f32; 3]; 2] {
        let down = |x: f64| {
            let f = x as f32;
            if f as f64 > x {
                f.next_down()
            } else {
                f
            }
        };
        let up = |x: f64| {
            let f = x as f32;
            if (f as f64) < x {
                f.next_up()
            } else {
                f
            }
        };
        [
            [down(self.lo[0]), down(self.lo[1]), down(self.lo[2])],
            [up(self.hi[0]), up(self.hi[1]), up(self.hi[2])],
        ]
    }
}

impl Bvh {
    /// Builds the hierarchy over `tris` (finite, non-degenerate triangles in
    /// origin-relative coordinates) with their global ids.
    pub fn build(tris: Vec<[[f64; 3]; 3]>, ids: Vec<u32>) -> Bvh {
        assert_eq!(tris.len(), ids.len());
        let n = tris.len();
        if n == 0 {
            return Bvh::default();
        }
        let boxes: Vec<Aabb> = tris
            .iter()
            .map(|t| {
                let mut b = Aabb::EMPTY;
                for p in t {
                    b.grow_point(p);
                }
                b
            })
            .collect();
        let centroids: Vec<[f64; 3]> = boxes
            .iter()
            .map(|b| {
                [
                    0.5 * (b.lo[0] + b.hi[0]),
                    0.5 * (b.lo[1] + b.hi[1]),
                    0.5 * (b.lo[2] + b.hi[2]),
                ]
            })
            .collect();
        let mut order: Vec<u32> = (0..n as u32).collect();
        let mut nodes = vec![Node::default()];
        nodes.reserve(2 * n);
        // (node index, start, end, depth)
        let mut work = vec![(0usize, 0usize, n, 0usize)];
        let mut max_depth = 0;
        while let Some((ni, s, e, depth)) = work.pop() {
            max_depth = max_depth.max(depth);
            let mut bounds = Aabb::EMPTY;
            let mut cbounds = Aabb::EMPTY;
            for &i in &order[s..e] {
                bounds.grow(&boxes[i as usize]);
                cbounds.grow_point(&centroids[i as usize]);
            }
            nodes[ni].bounds = bounds.to_f32();
            let count = e - s;
            let leaf = |nodes: &mut Vec<Node>| {
                nodes[ni].first = s as u32;
                nodes[ni].count = count as u32;
            };
            if count <= 1 {
                leaf(&mut nodes);
                continue;
            }
            let mut mid = None;
            if depth < SAH_DEPTH {
                match sah_split(&order[s..e], &boxes, &centroids, &cbounds, &bounds) {
                    Some((axis, bin, cost)) => {
                        if count <= MAX_LEAF && count as f64 <= cost {
                            leaf(&mut nodes);
                            continue;
                        }
                        let m = partition(&mut order[s..e], &centroids, &cbounds, axis, bin);
                        if m > 0 && m < count {
                            mid = Some(s + m);
                        }
                    }
                    None => {
                        if count <= MAX_LEAF {
                            leaf(&mut nodes);
                            continue;
                        }
                    }
                }
            } else if count <= 2 {
                leaf(&mut nodes);
                continue;
            }
            let mid = mid.unwrap_or_else(|| {
                // Object median along the widest centroid axis.
                let ext = [
                    cbounds.hi[0] - cbounds.lo[0],
                    cbounds.hi[1] - cbounds.lo[1],
                    cbounds.hi[2] - cbounds.lo[2],
                ];
                let axis = if ext[0] >= ext[1] && ext[0] >= ext[2] {
                    0
                } else if ext[1] >= ext[2] {
                    1
                } else {
                    2
                };
                let half = count / 2;
                order[s..e].select_nth_unstable_by(half, |&a, &b| {
                    centroids[a as usize][axis].total_cmp(&centroids[b as usize][axis])
                });
                s + half
            });
            let l = nodes.len();
            nodes.push(Node::default());
            nodes.push(Node::default());
            nodes[ni].first = l as u32;
            nodes[ni].count = 0;
            work.push((l + 1, mid, e, depth + 1));
            work.push((l, s, mid, depth + 1));
        }
        assert!(
            max_depth < STACK,
            "BVH depth {max_depth} exceeds the traversal stack"
        );
        let mut out_tris = Vec::with_capacity(n);
        let mut out_ids = Vec::with_capacity(n);
        for &i in &order {
            out_tris.push(tris[i as usize]);
            out_ids.push(ids[i as usize]);
        }
        Bvh {
            nodes,
            tris: out_tris,
            ids: out_ids,
            depth: max_depth,
        }
    }

    /// Depth of the tree (0 for a single leaf).
    pub fn depth(&self) -> usize {
        self.depth
    }

    /// Vertices of leaf-ordered triangle `index`.
    pub fn triangle(&self, index: u32) -> &[[f64; 3]; 3] {
        &self.tris[index as usize]
    }

    /// Global id of leaf-ordered triangle `index`.
    pub fn id(&self, index: u32) -> u32 {
        self.ids[index as usize]
    }

    /// The nearest hit with `t_min < t < t_max`; equal distances resolve
    /// to the smaller global id.
    /// Hits that `accept` (leaf-ordered index, hit) refuses are passed
    /// through (alpha-tested triangles where they are not opaque).
    pub fn nearest(
        &self,
        ray: &Ray,
        t_min: f64,
        t_max: f64,
        accept: &dyn Fn(u32, &Hit) -> bool,
    ) -> Option<NearestHit> {
        if self.nodes.is_empty() {
            return None;
        }
        ray.hit_box(&self.nodes[0].bounds, t_min, t_max)?;
        let mut best: Option<NearestHit> = None;
        let mut t_best = t_max;
        let mut stack = [(0u32, 0f64); STACK];
        let mut sp = 0;
        let mut ni = 0u32;
        loop {
            let node = &self.nodes[ni as usize];
            if node.count > 0 {
                for i in node.first..node.first + node.count {
                    // `t_best` itself is allowed so that ties reach the id rule.
                    let hi = if best.is_some() {
                        t_best.next_up()
                    } else {
                        t_best
                    };
                    if let Some(h) = ray
                        .intersect(&self.tris[i as usize], t_min, hi)
                        .filter(|h| accept(i, h))
                    {
                        let better = match best {
                            None => true,
                            Some(b) => {
                                h.t < b.hit.t
                                    || (h.t == b.hit.t && self.ids[i as usize] < self.id(b.index))
                            }
                        };
                        if better {
                            t_best = h.t;
                            best = Some(NearestHit { hit: h, index: i });
                        }
                    }
                }
            } else {
                let c0 = node.first;
                let h0 = ray.hit_box(&self.nodes[c0 as usize].bounds, t_min, t_best);
                let h1 = ray.hit_box(&self.nodes[c0 as usize + 1].bounds, t_min, t_best);
                match (h0, h1) {
                    (Some(a), Some(b)) => {
                        let (first, second, t2) = if a <= b {
                            (c0, c0 + 1, b)
                        } else {
                            (c0 + 1, c0, a)
                        };
                        stack[sp] = (second, t2);
                        sp += 1;
                        ni = first;
                        continue;
                    }
                    (Some(_), None) => {
                        ni = c0;
                        continue;
                    }
                    (None, Some(_)) => {
                        ni = c0 + 1;
                        continue;
                    }
                    (None, None) => {}
                }
            }
            // Pop the next node that may still hold a hit no farther than the best.
            loop {
                if sp == 0 {
                    return best;
                }
                sp -= 1;
                let (n, t_near) = stack[sp];
                if t_near <= t_best {
                    ni = n;
                    break;
                }
            }
        }
    }

    /// Whether any triangle whose global id is not `ignore` is hit with
    /// `t_min < t < t_max`. `hint` is a leaf-ordered triangle index tested
    /// first (the last occluder found, or `u32::MAX`); it is updated to the
    /// occluder found.
    /// Hits that `accept` refuses do not count.
    pub fn any_hit(
        &self,
        ray: &Ray,
        t_min: f64,
        t_max: f64,
        ignore: u32,
        hint: &mut u32,
        accept: &dyn Fn(u32, &Hit) -> bool,
    ) -> bool {
        if self.nodes.is_empty() {
            return false;
        }
        if let Some(tri) = self.tris.get(*hint as usize) {
            if self.ids[*hint as usize] != ignore
                && ray
                    .intersect(tri, t_min, t_max)
                    .is_some_and(|h| accept(*hint, &h))
            {
                return true;
            }
        }
        if ray.hit_box(&self.nodes[0].bounds, t_min, t_max).is_none() {
            return false;
        }
        let mut stack = [0u32; STACK];
        let mut sp = 0;
        let mut ni = 0u32;
        loop {
            let node = &self.nodes[ni as usize];
            if node.count > 0 {
                for i in node.first..node.first + node.count {
                    if self.ids[i as usize] != ignore
                        && ray
                            .intersect(&self.tris[i as usize], t_min, t_max)
                            .is_some_and(|h| accept(i, &h))
                    {
                        *hint = i;
                        return true;
                    }
                }
            } else {
                let c0 = node.first;
                let h0 = ray.hit_box(&self.nodes[c0 as usize].bounds, t_min, t_max);
                let h1 = ray.hit_box(&self.nodes[c0 as usize + 1].bounds, t_min, t_max);
                match (h0, h1) {
                    (Some(a), Some(b)) => {
                        let (first, second) = if a <= b { (c0, c0 + 1) } else { (c0 + 1, c0) };
                        stack[sp] = second;
                        sp += 1;
                        ni = first;
                        continue;
                    }
                    (Some(_), None) => {
                        ni = c0;
                        continue;
                    }
                    (None, Some(_)) => {
                        ni = c0 + 1;
                        continue;
                    }
                    (None, None) => {}
                }
            }
            if sp == 0 {
                return false;
            }
            sp -= 1;
            ni = stack[sp];
        }
    }
}

/// Best binned-SAH split of `prims`: (axis, last bin on the left, cost in
/// units of one triangle test), or `None` when all centroids coincide.
fn sah_split(
    prims: &[u32],
    boxes: &[Aabb],
    centroids: &[[f64; 3]],
    cb: &Aabb,
    bounds: &Aabb,
) -> Option<(usize, usize, f64)> {
    let mut bins = [[(Aabb::EMPTY, 0usize); BINS]; 3];
    let scale: [f64; 3] = std::array::from_fn(|k| {
        let ext = cb.hi[k] - cb.lo[k];
        if ext > 0.0 {
            BINS as f64 / ext
        } else {
            0.0
        }
    });
    if scale == [0.0; 3] {
        return None;
    }
    for &i in prims {
        let c = &centroids[i as usize];
        for k in 0..3 {
            if scale[k] > 0.0 {
                let b = bin_of(c[k], cb.lo[k], scale[k]);
                bins[k][b].0.grow(&boxes[i as usize]);
                bins[k][b].1 += 1;
            }
        }
    }
    let area = bounds.half_area();
    let inv_area = if area > 0.0 { 1.0 / area } else { 0.0 };
    let mut best: Option<(usize, usize, f64)> = None;
    for k in 0..3 {
        if scale[k] == 0.0 {
            continue;
        }
        // Right-to-left sweep: cost of the right side for splits after bin b.
        let mut right = [0.0; BINS];
        let mut acc = Aabb::EMPTY;
        let mut cnt = 0;
        for b in (1..BINS).rev() {
            acc.grow(&bins[k][b].0);
            cnt += bins[k][b].1;
            right[b - 1] = acc.half_area() * cnt as f64;
        }
        let mut acc = Aabb::EMPTY;
        let mut cnt = 0;
        for b in 0..BINS - 1 {
            acc.grow(&bins[k][b].0);
            cnt += bins[k][b].1;
            if cnt == 0 || cnt == prims.len() {
                continue;
            }
            let cost = TRAVERSAL_COST + (acc.half_area() * cnt as f64 + right[b]) * inv_area;
            if best.is_none_or(|(_, _, c)| cost < c) {
                best = Some((k, b, cost));
            }
        }
    }
    best
}

#[inline]
fn bin_of(c: f64, lo: f64, scale: f64) -> usize {
    (((c - lo) * scale) as usize).min(BINS - 1)
}

/// Moves the primitives whose centroid bin on `axis` is at most `bin` to the
/// front; returns how many there are.
fn partition(
    prims: &mut [u32],
    centroids: &[[f64; 3]],
    cb: &Aabb,
    axis: usize,
    bin: usize,
) -> usize {
    let scale = BINS as f64 / (cb.hi[axis] - cb.lo[axis]);
    let left = |i: u32| bin_of(centroids[i as usize][axis], cb.lo[axis], scale) <= bin;
    let mut i = 0;
    let mut j = prims.len();
    while i < j {
        if left(prims[i]) {
            i += 1;
        } else {
            j -= 1;
            prims.swap(i, j);
        }
    }
    i
}
