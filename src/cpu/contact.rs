//! Whether two solids overlap: CIGI's collision detection volumes (spheres and cuboids)
//! placed anywhere on the earth, each held in ECEF (centre, axes, half sizes). Spheres against
//! spheres and cuboids by their closest point, cuboids against cuboids by the separating-axis
//! test (the 15 axes of two boxes).

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
}
