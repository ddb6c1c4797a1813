//! Whether two solids overlap: CIGI's collision detection volumes (spheres and cuboids)
//! placed anywhere on the earth, each held in ECEF (centre, axes, half sizes). Spheres against
//! spheres and cuboids by their closest point, cuboids against cuboids by the separating-axis
//! test (the 15 axes of two boxes). Against the terrain a solid is taken by its underside
//! ([`underside`]): the lowest point of each of a grid of vertical lines through it.

use glam::{DMat3, DVec3};

/// A solid in ECEF metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Solid {
    Sphere {
        centre: DVec3,
        radius: f64,
    },
    /// A box: its centre, its unit axes and its half sizes along them.
    Cuboid {
        centre: DVec3,
        axes: DMat3,
        half: DVec3,
    },
}

/// Whether `a` and `b` overlap (touching counts).
pub fn overlap(a: &Solid, b: &Solid) -> bool {
    match (a, b) {
        (
            Solid::Sphere {
                centre: p,
                radius: r,
            },
            Solid::Sphere {
                centre: q,
                radius: s,
            },
        ) => p.distance(*q) <= r + s,
        (
            Solid::Sphere { centre, radius },
            Solid::Cuboid {
                centre: c,
                axes,
                half,
            },
        )
        | (
            Solid::Cuboid {
                centre: c,
                axes,
                half,
            },
            Solid::Sphere { centre, radius },
        ) => {
            let d = *centre - *c;
            let local = axes.transpose() * d;
            let nearest = local.clamp(-*half, *half);
            (local - nearest).length() <= *radius
        }
        (
            Solid::Cuboid {
                centre: ca,
                axes: aa,
                half: ha,
            },
            Solid::Cuboid {
                centre: cb,
                axes: ab,
                half: hb,
            },
        ) => boxes_overlap(*ca, aa, *ha, *cb, ab, *hb),
    }
}

/// The separating-axis test of two boxes: separated when the projections of the boxes on one
/// of their 6 face normals or 9 edge cross products do not meet.
fn boxes_overlap(ca: DVec3, aa: &DMat3, ha: DVec3, cb: DVec3, ab: &DMat3, hb: DVec3) -> bool {
    let a = [aa.x_axis, aa.y_axis, aa.z_axis];
    let b = [ab.x_axis, ab.y_axis, ab.z_axis];
    let d = cb - ca;
    let radius = |axes: &[DVec3; 3], half: DVec3, l: DVec3| {
        half.x * axes[0].dot(l).abs()
            + half.y * axes[1].dot(l).abs()
            + half.z * axes[2].dot(l).abs()
    };
    let mut axes = [DVec3::ZERO; 15];
    axes[..3].copy_from_slice(&a);
    axes[3..6].copy_from_slice(&b);
    for (k, (u, v)) in a
        .iter()
        .flat_map(|u| b.iter().map(move |v| (u, v)))
        .enumerate()
    {
        axes[6 + k] = u.cross(*v);
    }
    // Parallel edges give no cross product: the face normals decide there.
    axes.iter()
        .filter(|l| l.length_squared() > 1e-12)
        .map(|l| l.normalize())
        .all(|l| d.dot(l).abs() <= radius(&a, ha, l) + radius(&b, hb, l))
}

/// The underside of `solid`: for each of `n` x `n` vertical lines (along unit `up`) through
/// its horizontal extent (unit `east` and `north` across it), the solid's lowest point on that
/// line, where the line meets it, and the solid's lowest point itself (first). A heightfield
/// that holds any point of the solid below it holds one of these below it up to what lies
/// between the lines: the solid's bottom between two of them no farther below them than its
/// slope over their spacing allows.
pub fn underside(solid: &Solid, [east, north, up]: [DVec3; 3], n: usize) -> Vec<DVec3> {
    let n = n.max(2);
    let (centre, reach) = match *solid {
        Solid::Sphere { centre, radius } => (centre, [radius; 2]),
        Solid::Cuboid { centre, axes, half } => {
            let across = |e: DVec3| (axes.transpose() * e).abs().dot(half);
            (centre, [across(east), across(north)])
        }
    };
    let mut out = vec![lowest_point(solid, up)];
    for i in 0..n {
        for j in 0..n {
            let f = |k: usize| k as f64 / (n - 1) as f64 * 2.0 - 1.0;
            let (u, v) = (f(i) * reach[0], f(j) * reach[1]);
            let foot = centre + east * u + north * v;
            if let Some(s) = lowest_on_line(solid, foot, up) {
                out.push(foot + up * s);
            }
        }
    }
    out
}

/// The lowest point of `solid` along unit `up`: a sphere's bottom, a cuboid's lowest corner.
pub fn lowest_point(solid: &Solid, up: DVec3) -> DVec3 {
    match *solid {
        Solid::Sphere { centre, radius } => centre - up * radius,
        Solid::Cuboid { centre, axes, half } => {
            // The corner farthest down: each axis's sign against `up`.
            let s = (axes.transpose() * up).map(|a| if a > 0.0 { -1.0 } else { 1.0 });
            centre + axes * (s * half)
        }
    }
}

/// Where the vertical line `foot + s up` enters `solid` from below: the least `s` in it.
fn lowest_on_line(solid: &Solid, foot: DVec3, up: DVec3) -> Option<f64> {
    match *solid {
        Solid::Sphere { centre, radius } => {
            let o = foot - centre;
            let b = o.dot(up);
            let d = b * b - (o.length_squared() - radius * radius);
            (d >= 0.0).then(|| -b - d.sqrt())
        }
        Solid::Cuboid { centre, axes, half } => {
            let (q, a) = (axes.transpose() * (foot - centre), axes.transpose() * up);
            let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
            for k in 0..3 {
                if a[k].abs() < 1e-12 {
                    if q[k].abs() > half[k] {
                        return None;
                    }
                    continue;
                }
                let (t0, t1) = ((-half[k] - q[k]) / a[k], (half[k] - q[k]) / a[k]);
                lo = lo.max(t0.min(t1));
                hi = hi.min(t0.max(t1));
            }
            (lo <= hi).then_some(lo)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cube(centre: DVec3, axes: DMat3, half: f64) -> Solid {
        Solid::Cuboid {
            centre,
            axes,
            half: DVec3::splat(half),
        }
    }

    #[test]
    fn spheres_boxes_and_turned_boxes() {
        let s = |x: f64, r: f64| Solid::Sphere {
            centre: DVec3::new(x, 0.0, 0.0),
            radius: r,
        };
        assert!(overlap(&s(0.0, 1.0), &s(1.99, 1.0)));
        assert!(!overlap(&s(0.0, 1.0), &s(2.01, 1.0)));
        let unit = cube(DVec3::ZERO, DMat3::IDENTITY, 1.0);
        assert!(overlap(&unit, &s(1.99, 1.0)));
        assert!(!overlap(&unit, &s(2.01, 1.0)));
        // Past the corner: the sphere's centre 1.01 beyond it along the diagonal.
        let far = DVec3::splat(1.0 + 1.01 / 3f64.sqrt());
        let corner = Solid::Sphere {
            centre: far,
            radius: 1.0,
        };
        assert!(!overlap(&unit, &corner));
        assert!(overlap(
            &unit,
            &cube(DVec3::new(1.99, 0.0, 0.0), DMat3::IDENTITY, 1.0)
        ));
        assert!(!overlap(
            &unit,
            &cube(DVec3::new(2.01, 0.0, 0.0), DMat3::IDENTITY, 1.0)
        ));
        // Turned 45° about z, a cube reaches √2 along x: it meets the unit cube 2.4 away, not
        // 2.42 (1 + √2 = 2.414).
        let turned = DMat3::from_rotation_z(std::f64::consts::FRAC_PI_4);
        assert!(overlap(
            &unit,
            &cube(DVec3::new(2.40, 0.0, 0.0), turned, 1.0)
        ));
        assert!(!overlap(
            &unit,
            &cube(DVec3::new(2.42, 0.0, 0.0), turned, 1.0)
        ));
        // An edge-on pair only the cross products separate.
        let a = DMat3::from_rotation_y(std::f64::consts::FRAC_PI_4);
        let b = DMat3::from_rotation_x(std::f64::consts::FRAC_PI_4);
        // Their edges cross at heights √2 above and below the centres, along y and x: only
        // z (an edge cross product) separates them.
        let edge = |d: f64| cube(DVec3::new(0.0, 0.0, d), b, 1.0);
        let under = cube(DVec3::ZERO, a, 1.0);
        assert!(
            !overlap(&under, &edge(2.0 * 2f64.sqrt() + 0.05)),
            "separated edge on"
        );
        assert!(
            overlap(&under, &edge(2.0 * 2f64.sqrt() - 0.05)),
            "crossed edge on"
        );
    }

    /// Every underside point lies on the solid's surface, none lower than its lowest point,
    /// and the lowest point is the analytic one (a sphere's bottom; a pitched box's lower end).
    #[test]
    fn undersides_lie_on_the_surface_and_the_lowest_point_comes_first() {
        let frame = [DVec3::X, DVec3::Y, DVec3::Z];
        let c = DVec3::new(10.0, -4.0, 7.0);
        let sphere = Solid::Sphere {
            centre: c,
            radius: 3.0,
        };
        let pts = underside(&sphere, frame, 9);
        assert_eq!(pts[0], c - DVec3::Z * 3.0);
        assert!(pts.len() > 40, "{}", pts.len());
        for p in &pts {
            assert!(((*p - c).length() - 3.0).abs() < 1e-9, "{p}");
            assert!(p.z <= c.z + 1e-9 && p.z >= pts[0].z - 1e-9, "{p}");
        }
        // A box 40 x 10 x 6 pitched 20° nose up: its lowest edge is the tail's bottom,
        // 20 sin 20° + 3 cos 20° below the centre.
        let p = 20f64.to_radians();
        let axes = DMat3::from_cols(
            DVec3::new(p.cos(), 0.0, p.sin()),
            DVec3::Y,
            DVec3::new(-p.sin(), 0.0, p.cos()),
        );
        let half = DVec3::new(20.0, 5.0, 3.0);
        let cuboid = Solid::Cuboid {
            centre: c,
            axes,
            half,
        };
        let pts = underside(&cuboid, frame, 17);
        let drop = 20.0 * p.sin() + 3.0 * p.cos();
        assert!((pts[0].z - (c.z - drop)).abs() < 1e-9, "{}", pts[0]);
        for q in &pts {
            let l = axes.transpose() * (*q - c);
            let on_face = (0..3).any(|k| (l[k].abs() - half[k]).abs() < 1e-9);
            assert!(
                on_face && (0..3).all(|k| l[k].abs() <= half[k] + 1e-9),
                "{l}"
            );
            assert!(q.z >= pts[0].z - 1e-9, "{q}");
        }
        // Lines across the whole footprint: the lowest row spans the box's width.
        let ys: Vec<f64> = pts.iter().map(|q| q.y).collect();
        let span = ys.iter().cloned().fold(f64::MIN, f64::max)
            - ys.iter().cloned().fold(f64::MAX, f64::min);
        assert!((span - 10.0).abs() < 1e-9, "{span}");
    }
}
