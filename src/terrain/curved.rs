//! The curved earth in the grid frame: the drop of the WGS84 surface below the tangent plane
//! of the eye, as a quadratic form in grid coordinates, so that traversals can fold it into
//! their bound tests and exact patch quadratics (see `docs/database.md#curved-earth`).

use super::heightfield::metres_per_degree;
use super::Terrain;
use crate::geodesy::Curvature;
use glam::{DVec2, DVec3};

/// The eye's osculating paraboloid in the grid frame: a point at grid `(x, y)` lies
/// `k.x·(x − eye.x)² + k.y·(y − eye.y)²` metres below the eye's tangent plane (the base plane
/// through the eye's foot). Flat terrain: `k = 0`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridCurvature {
    /// The eye's grid position (x, y).
    pub eye: DVec2,
    /// Drop per squared grid step along x and y (metres): `s.x²/(2N)`, `s.y²/(2M)`, with
    /// `s` the metres of a grid step at the eye's latitude.
    pub k: DVec2,
    /// Metres of a grid step at the eye's latitude over the terrain frame's spacing (taken
    /// at the window's centre latitude), along x and y: the picture's horizontal metric is
    /// the eye's, so that the ground around the eye has its true size whatever the window.
    /// `(1, 1)` on a flat terrain.
    pub metric: DVec2,
}

impl GridCurvature {
    /// No curvature.
    pub const FLAT: GridCurvature = GridCurvature {
        eye: DVec2::ZERO,
        k: DVec2::ZERO,
        metric: DVec2::ONE,
    };

    /// Drop (m) below the eye's tangent plane at grid `(x, y)`.
    pub fn drop(&self, x: f64, y: f64) -> f64 {
        let (dx, dy) = (x - self.eye.x, y - self.eye.y);
        self.k.x * dx * dx + self.k.y * dy * dy
    }

    /// Gradient of the drop (metres per grid step) at grid `(x, y)`.
    pub fn drop_gradient(&self, x: f64, y: f64) -> DVec2 {
        DVec2::new(
            2.0 * self.k.x * (x - self.eye.x),
            2.0 * self.k.y * (y - self.eye.y),
        )
    }

    /// Largest drop over a grid of `cells` (at its corner farthest from the eye).
    pub fn max_drop(&self, cells: [usize; 2]) -> f64 {
        let far = |e: f64, n: usize| e.abs().max((n as f64 - e).abs());
        self.k.x * far(self.eye.x, cells[0]).powi(2) + self.k.y * far(self.eye.y, cells[1]).powi(2)
    }

    pub fn is_flat(&self) -> bool {
        self.k == DVec2::ZERO && self.metric == DVec2::ONE
    }

    /// A world-frame vector (terrain axes x, y, normal) as the eye's metric measures it: its
    /// components along the grid axes scaled by [`Self::metric`] (for a frame whose axes are
    /// the world's x and y, as a georeferenced terrain's are).
    pub fn metric_vector(&self, v: DVec3) -> DVec3 {
        DVec3::new(v.x * self.metric.x, v.y * self.metric.y, v.z)
    }
}

impl Terrain {
    /// The curvature seen from the world point `eye`: [`GridCurvature::FLAT`] unless the
    /// terrain is curved (`terrain.curved`), else the paraboloid at the eye's latitude and the
    /// metres of a grid step there (the grid's axes are east and north).
    pub fn curvature(&self, eye: DVec3) -> GridCurvature {
        let (true, Some(geo)) = (self.curved, self.field.geo) else {
            return GridCurvature::FLAT;
        };
        let g = self.frame.world_to_grid(eye);
        let lat = (geo.lat0 + g.y * geo.dlat).clamp(-90.0, 90.0);
        let c = Curvature::at(lat);
        let (mx, my) = metres_per_degree(lat);
        let (sx, sy) = (geo.dlon.abs() * mx, geo.dlat.abs() * my);
        let [fx, fy] = self.frame.spacing;
        GridCurvature {
            eye: DVec2::new(g.x, g.y),
            k: DVec2::new(c.east * sx * sx, c.north * sy * sy),
            metric: DVec2::new(sx / fx, sy / fy),
        }
    }
}
