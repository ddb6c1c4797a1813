//! Quadric free forms (the paper's second primitive class, seed-digest §1): a base quadric
//! `F(x,y,z) = Ax²+By²+Cz²+Dxy+Exz+Fyz+Gx+Hy+Iz+K` plus perturbations `R = w·Q²` where
//! `Q > 0` (else 0), each `Q` itself a perturbed quadric (recursive). The solid is
//! `F' = F + ΣR ≤ 0` clipped to the object's bounding box. No GPU types live here.
//!
//! Each object has a rigid placement (rotation + translation, so ray distances are the same in
//! the object frame and the world) and its perturbation tree is stored flattened in pre-order:
//! a node's subtree is the contiguous run after it. Evaluating in reverse order therefore
//! meets every node after all of its descendants, which lets the GPU evaluate the tree without
//! recursion.

mod desc;

pub use desc::{FreeFormDesc, MaterialDesc};

use glam::{DMat3, DVec3};

/// Most nodes (base quadric + perturbations) one object may have.
pub const MAX_NODES: usize = 16;
/// Most free forms one scene may have (object ids fit the G-buffer's 16 bits).
pub const MAX_OBJECTS: usize = 65_535;
/// Deepest perturbation nesting: the base is depth 0, its perturbations depth 1, ...
pub const MAX_DEPTH: u32 = 3;
/// Most cells [`FreeForm::gradient_bound`] bounds one by one.
const GRADIENT_CELLS: usize = 4096;
/// [`FreeForm::gradient_bound`] stops when its bound is within this factor of a gradient found.
const GRADIENT_SLACK: f64 = 1.5;

/// A box of [`FreeForm::gradient_bound`]'s search, ordered by its bound.
struct Cell {
    bound: f64,
    lo: DVec3,
    hi: DVec3,
}

impl PartialEq for Cell {
    fn eq(&self, o: &Cell) -> bool {
        self.bound.total_cmp(&o.bound).is_eq()
    }
}

impl Eq for Cell {}

impl PartialOrd for Cell {
    fn partial_cmp(&self, o: &Cell) -> Option<std::cmp::Ordering> {
        Some(self.cmp(o))
    }
}

impl Ord for Cell {
    fn cmp(&self, o: &Cell) -> std::cmp::Ordering {
        self.bound.total_cmp(&o.bound)
    }
}

/// A quadric `Ax²+By²+Cz²+Dxy+Exz+Fyz+Gx+Hy+Iz+K`; coefficients in that order.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Quadric(pub [f64; 10]);

impl Quadric {
    /// Value at `p`.
    pub fn eval(&self, p: DVec3) -> f64 {
        let [a, b, c, d, e, f, g, h, i, k] = self.0;
        let (x, y, z) = (p.x, p.y, p.z);
        x * (a * x + d * y + e * z + g) + y * (b * y + f * z + h) + z * (c * z + i) + k
    }

    /// Gradient at `p`.
    pub fn grad(&self, p: DVec3) -> DVec3 {
        let [a, b, c, d, e, f, g, h, i, _] = self.0;
        DVec3::new(
            2.0 * a * p.x + d * p.y + e * p.z + g,
            2.0 * b * p.y + d * p.x + f * p.z + h,
            2.0 * c * p.z + e * p.x + f * p.y + i,
        )
    }

    /// Symmetric matrix `M`, linear part `g` and constant `k` with `Q = pᵀMp + g·p + k`.
    pub fn parts(&self) -> (DMat3, DVec3, f64) {
        let [a, b, c, d, e, f, g, h, i, k] = self.0;
        let m = DMat3::from_cols(
            DVec3::new(a, 0.5 * d, 0.5 * e),
            DVec3::new(0.5 * d, b, 0.5 * f),
            DVec3::new(0.5 * e, 0.5 * f, c),
        );
        (m, DVec3::new(g, h, i), k)
    }

    fn from_parts(m: DMat3, g: DVec3, k: f64) -> Quadric {
        Quadric([
            m.x_axis.x,
            m.y_axis.y,
            m.z_axis.z,
            m.y_axis.x + m.x_axis.y,
            m.z_axis.x + m.x_axis.z,
            m.z_axis.y + m.y_axis.z,
            g.x,
            g.y,
            g.z,
            k,
        ])
    }

    /// Coefficients `(α, β, γ)` of `Q(o + s d) = α s² + β s + γ`.
    pub fn along(&self, o: DVec3, d: DVec3) -> [f64; 3] {
        let (m, g, _) = self.parts();
        let md = m * d;
        [d.dot(md), 2.0 * o.dot(md) + g.dot(d), self.eval(o)]
    }

    /// The quadric moved rigidly: `Q'(p) = Q(Rᵀ(p − c))` (a shape defined around its own
    /// origin, rotated by `rot` and centred at `c`).
    pub fn moved(&self, rot: DMat3, c: DVec3) -> Quadric {
        let (m0, g0, k0) = self.parts();
        let m = rot * m0 * rot.transpose();
        let g1 = rot * g0;
        let g = g1 - 2.0 * (m * c);
        let k = c.dot(m * c) - g1.dot(c) + k0;
        Quadric::from_parts(m, g, k)
    }

    /// Enclosures of the value and of each gradient component over the box `[lo, hi]`, in
    /// centred form around its centre `c` (`δ` within the half-extents `h`): `Q(c + δ) =
    /// Q(c) + Σ (∂ᵢQ(c) δᵢ + Mᵢᵢ δᵢ²) + Σ 2Mᵢⱼ δᵢ δⱼ`, each axis's quadratic exact on its
    /// interval (so the value range is exact for a quadric without cross terms), each cross
    /// term bounded by `|2Mᵢⱼ| hᵢ hⱼ`; each gradient component `∇Q(c) + 2Mδ` is linear, so
    /// its range is exact.
    pub fn box_ranges(&self, lo: DVec3, hi: DVec3) -> (Interval, [Interval; 3]) {
        let (m, _, _) = self.parts();
        let (c, h) = (0.5 * (lo + hi), 0.5 * (hi - lo));
        let g = self.grad(c);
        let mut value = Interval::point(self.eval(c));
        for i in 0..3 {
            let (a, b) = quadratic_range([m.col(i)[i], g[i], 0.0], -h[i], h[i]);
            value = value + Interval::new(a, b);
            for j in i + 1..3 {
                let r = 2.0 * (m.col(j)[i] * h[i] * h[j]).abs();
                value = value + Interval::new(-r, r);
            }
        }
        let grad = [0, 1, 2].map(|k| {
            let r = 2.0 * (0..3).map(|j| (m.col(j)[k] * h[j]).abs()).sum::<f64>();
            Interval::new(g[k] - r, g[k] + r)
        });
        (value, grad)
    }

    /// `-Q`.
    pub fn negated(&self) -> Quadric {
        Quadric(self.0.map(|v| -v))
    }

    /// True when every coefficient except the constant is zero.
    pub fn is_constant(&self) -> bool {
        self.0[..9].iter().all(|v| *v == 0.0)
    }
}

/// One node of a flattened perturbation tree.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Node {
    /// The quadric in the object frame.
    pub q: Quadric,
    /// `R = weight · max(Q', 0)²` is added to the parent (unused for the base, depth 0).
    pub weight: f64,
    /// 0 for the base quadric, parent depth + 1 for perturbations.
    pub depth: u32,
}

/// Surface appearance: the paper's colour formula
/// `C = (Qa·Ca + Qd·Cd + Qs·Cs)/(Qa+Qd+Qs)`, `Cd = (n·l)·Clight·Csurf`, `Cs = (r·v)^p·Clight`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    /// Linear RGB surface colour `Csurf`.
    pub colour: [f32; 3],
    /// `Qa`, weight of the ambient term (`Ca` = sky light · `Csurf`).
    pub ambient: f32,
    /// `Qd`, weight of the diffuse term.
    pub diffuse: f32,
    /// `Qs`, weight of the specular term.
    pub specular: f32,
    /// `p`, the specular exponent.
    pub shininess: f32,
}

/// A placed free form.
#[derive(Clone, Debug, PartialEq)]
pub struct FreeForm {
    pub name: String,
    /// World-from-object rotation (columns: object x, y, z axes in the world).
    pub rotation: DMat3,
    /// World position of the object origin.
    pub position: DVec3,
    /// Base quadric first, then perturbations in pre-order (see the module docs).
    pub nodes: Vec<Node>,
    /// Bounding box in the object frame: the solid is `F' ≤ 0` inside it.
    pub bounds: [DVec3; 2],
    pub material: Material,
}

impl FreeForm {
    /// World point -> object frame.
    pub fn to_local(&self, p: DVec3) -> DVec3 {
        self.rotation.transpose() * (p - self.position)
    }

    /// The object moved rigidly by `offset` (world metres).
    pub fn translated(&self, offset: DVec3) -> FreeForm {
        FreeForm {
            position: self.position + offset,
            ..self.clone()
        }
    }

    /// World direction -> object frame.
    pub fn dir_to_local(&self, d: DVec3) -> DVec3 {
        self.rotation.transpose() * d
    }

    /// World-space bounding sphere (centre, radius) of the bounding box.
    pub fn bounding_sphere(&self) -> (DVec3, f64) {
        let [lo, hi] = self.bounds;
        (
            self.position + self.rotation * (0.5 * (lo + hi)),
            0.5 * (hi - lo).length(),
        )
    }

    /// `F'` at an object-frame point.
    pub fn value(&self, p: DVec3) -> f64 {
        self.value_grad(p).0
    }

    /// `F'` and its gradient at an object-frame point. The gradient is continuous: each
    /// perturbation adds `2·w·max(Q',0)·∇Q'`.
    pub fn value_grad(&self, p: DVec3) -> (f64, DVec3) {
        let mut acc = [(0.0, DVec3::ZERO); MAX_DEPTH as usize + 2];
        for n in self.nodes.iter().rev() {
            let d = n.depth as usize;
            let (cv, cg) = std::mem::take(&mut acc[d + 1]);
            let v = n.q.eval(p) + cv;
            let g = n.q.grad(p) + cg;
            if d == 0 {
                return (v, g);
            }
            let pos = v.max(0.0);
            acc[d].0 += n.weight * pos * pos;
            acc[d].1 += 2.0 * n.weight * pos * g;
        }
        unreachable!("node 0 is the base quadric at depth 0")
    }

    /// An enclosure `[lo, hi]` of `F'(o + s d)` over `s ∈ [a, b]`, from the per-node
    /// coefficients `coef[i] = nodes[i].q.along(o, d)`. Each quadric's range on the interval
    /// is exact; `w·max(·,0)²` is monotone, so the only overestimate is the sum of ranges.
    pub fn enclose(&self, coef: &[[f64; 3]], a: f64, b: f64) -> (f64, f64) {
        let mut acc = [(0.0, 0.0); MAX_DEPTH as usize + 2];
        for (n, c) in self.nodes.iter().zip(coef).rev() {
            let d = n.depth as usize;
            let (clo, chi) = std::mem::take(&mut acc[d + 1]);
            let (lo, hi) = quadratic_range(*c, a, b);
            let (lo, hi) = (lo + clo, hi + chi);
            if d == 0 {
                return (lo, hi);
            }
            let (rl, rh) = (
                n.weight * lo.max(0.0).powi(2),
                n.weight * hi.max(0.0).powi(2),
            );
            acc[d].0 += rl.min(rh);
            acc[d].1 += rl.max(rh);
        }
        unreachable!("node 0 is the base quadric at depth 0")
    }

    /// Is the solid convex? True for a plain object (no perturbations) whose quadric has a
    /// positive semi-definite quadratic part: `F` is then a convex function, its sublevel set
    /// `F ≤ 0` is convex and so is its intersection with the box (boxes, spheres, ellipsoids,
    /// cylinders, paraboloids, planes; not cones or hyperboloids). A ray leaving a convex
    /// solid's surface outwards never meets it again: the shadow binning uses this.
    pub fn is_convex(&self) -> bool {
        let [node] = self.nodes.as_slice() else {
            return false;
        };
        let [a, b, c, d, e, f, ..] = node.q.0;
        let scale = [a, b, c, d, e, f]
            .iter()
            .fold(0.0f64, |m, v| m.max(v.abs()));
        if scale == 0.0 {
            return true; // linear: a half-space
        }
        // All principal minors of [[a d e] [d b f] [e f c]] / scale non-negative, to rounding.
        let [a, b, c] = [a, b, c].map(|v| v / scale);
        let [d, e, f] = [d, e, f].map(|v| 0.5 * v / scale);
        let minors = [
            a,
            b,
            c,
            a * b - d * d,
            a * c - e * e,
            b * c - f * f,
            a * (b * c - f * f) - d * (d * c - f * e) + e * (d * f - b * e),
        ];
        minors.iter().all(|&m| m >= -1e-9)
    }

    /// A bound on `|∇F'|` over the bounding box widened by `margin` each way (object frame):
    /// per node, enclosures of `Q'` and a bound on `|∇Q'|` from its quadric's
    /// ([`Quadric::box_ranges`]) plus its children's, each child adding `w·max(Q',0)²`,
    /// whose gradient `2·w·max(Q',0)·∇Q'` is at most `2·|w|·max(Q'.hi, 0)·|∇Q'|`.
    /// Anti-aliasing's near misses of perturbed objects use it: a point within `r` of the
    /// solid has `F' <= bound · r` (the segment to the solid lies in the widened box while
    /// `r <= margin`).
    pub fn gradient_bound(&self, margin: f64) -> f64 {
        // Branch and bound: the cell with the largest bound is halved along its longest side
        // (an enclosure over a smaller box is tighter, and a perturbation is zero on the cells
        // it does not reach) until that bound is within GRADIENT_SLACK of the largest |∇F'|
        // found at a cell centre, or GRADIENT_CELLS cells were made. The largest bound left
        // bounds every cell.
        let bounded = |lo: DVec3, hi: DVec3| Cell {
            bound: self.cell_gradient_bound(lo, hi),
            lo,
            hi,
        };
        let (lo, hi) = (self.bounds[0] - margin, self.bounds[1] + margin);
        let mut found = self.value_grad(0.5 * (lo + hi)).1.length();
        let mut cells = std::collections::BinaryHeap::from([bounded(lo, hi)]);
        for _ in 0..GRADIENT_CELLS / 2 {
            let top = cells.pop().expect("a cell is pushed back for each popped");
            // A NaN bound (a degenerate object) stops too: the search only makes it NaN again.
            if top.bound <= GRADIENT_SLACK * found || top.bound.is_nan() {
                return top.bound;
            }
            let axis = (top.hi - top.lo).max_position();
            let mut mid = top.hi;
            mid[axis] = 0.5 * (top.lo[axis] + top.hi[axis]);
            let mut start = top.lo;
            start[axis] = mid[axis];
            for (a, b) in [(top.lo, mid), (start, top.hi)] {
                found = found.max(self.value_grad(0.5 * (a + b)).1.length());
                cells.push(bounded(a, b));
            }
        }
        cells.peek().map_or(f64::INFINITY, |c| c.bound)
    }

    /// [`Self::gradient_bound`] over one box `[lo, hi]`.
    fn cell_gradient_bound(&self, lo: DVec3, hi: DVec3) -> f64 {
        // Per depth: the children's summed value enclosure and gradient bound.
        let mut acc = [(Interval::point(0.0), 0.0); MAX_DEPTH as usize + 2];
        for n in self.nodes.iter().rev() {
            let d = n.depth as usize;
            let (cv, cg) = std::mem::replace(&mut acc[d + 1], (Interval::point(0.0), 0.0));
            let (v, g) = n.q.box_ranges(lo, hi);
            let v = v + cv;
            let g = g
                .map(|c| c.magnitude())
                .iter()
                .map(|m| m * m)
                .sum::<f64>()
                .sqrt()
                + cg;
            if d == 0 {
                return g;
            }
            let top = v.hi.max(0.0);
            let r = Interval::new(v.lo.max(0.0).powi(2), top * top).scale(n.weight);
            acc[d].0 = acc[d].0 + r;
            acc[d].1 += 2.0 * n.weight.abs() * top * g;
        }
        unreachable!("node 0 is the base quadric at depth 0")
    }

    /// Half the bounding-box diagonal: the object's size scale.
    pub fn size(&self) -> f64 {
        0.5 * (self.bounds[1] - self.bounds[0]).length()
    }
}

/// Exact range of `c0 s² + c1 s + c2` over `[a, b]`.
pub fn quadratic_range(c: [f64; 3], a: f64, b: f64) -> (f64, f64) {
    let f = |s: f64| (c[0] * s + c[1]) * s + c[2];
    let (fa, fb) = (f(a), f(b));
    let (mut lo, mut hi) = (fa.min(fb), fa.max(fb));
    if c[0] != 0.0 {
        let sv = -c[1] / (2.0 * c[0]);
        if sv > a && sv < b {
            let fv = f(sv);
            lo = lo.min(fv);
            hi = hi.max(fv);
        }
    }
    (lo, hi)
}

/// A closed interval `[lo, hi]` of reals, for enclosures over boxes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Interval {
    pub lo: f64,
    pub hi: f64,
}

impl Interval {
    /// `[min(a, b), max(a, b)]`.
    pub fn new(a: f64, b: f64) -> Interval {
        Interval {
            lo: a.min(b),
            hi: a.max(b),
        }
    }

    pub fn point(v: f64) -> Interval {
        Interval { lo: v, hi: v }
    }

    /// `{v·s}`.
    pub fn scale(self, s: f64) -> Interval {
        Interval::new(self.lo * s, self.hi * s)
    }

    /// The largest `|v|`.
    pub fn magnitude(self) -> f64 {
        self.lo.abs().max(self.hi.abs())
    }
}

impl std::ops::Add for Interval {
    type Output = Interval;
    fn add(self, o: Interval) -> Interval {
        Interval {
            lo: self.lo + o.lo,
            hi: self.hi + o.hi,
        }
    }
}
