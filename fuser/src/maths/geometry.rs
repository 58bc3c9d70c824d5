//! Rotated 3D box geometry: exact bird's-eye-view intersection of yawed rectangles (convex
//! polygon clipping), 3D IoU (BEV intersection x z-overlap), 3D GIoU and BEV IoU. Used by the
//! baselines.
//!
//! The 3D GIoU is the convention of the 3D tracking literature (AB3DMOT, SimpleTrack): IoU minus
//! the share of the enclosing volume C left out of the union, with C the BEV convex hull of both
//! footprints times the union of the z-extents.
//!
//! Corners are computed relative to the first box's centre, not in map coordinates: at
//! UTM-scale coordinates (10^5-10^6 m) map-frame corner products lose about 10^-3 of the area
//! to rounding; relative ones keep it to 10^-15.

use v2x_protocol::Detection;

/// A point in the plane (x, y).
pub type Pt = [f64; 2];

/// Signed area of a polygon (positive when counter-clockwise).
pub fn polygon_area(p: &[Pt]) -> f64 {
    let n = p.len();
    if n < 3 {
        return 0.0;
    }
    let mut s = 0.0;
    for i in 0..n {
        let (a, b) = (p[i], p[(i + 1) % n]);
        s += a[0] * b[1] - a[1] * b[0];
    }
    s / 2.0
}

fn cross(o: Pt, a: Pt, b: Pt) -> f64 {
    (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
}

/// Intersection of two convex counter-clockwise polygons (Sutherland-Hodgman clipping).
pub fn clip_convex(subject: &[Pt], clip: &[Pt]) -> Vec<Pt> {
    let mut out: Vec<Pt> = subject.to_vec();
    let n = clip.len();
    for i in 0..n {
        if out.is_empty() {
            break;
        }
        let (a, b) = (clip[i], clip[(i + 1) % n]);
        let input = std::mem::take(&mut out);
        let m = input.len();
        for k in 0..m {
            let (p, q) = (input[k], input[(k + 1) % m]);
            let (cp, cq) = (cross(a, b, p), cross(a, b, q));
            if cp >= 0.0 {
                out.push(p);
            }
            if (cp >= 0.0) != (cq >= 0.0) {
                let t = cp / (cp - cq);
                out.push([p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])]);
            }
        }
    }
    out
}

/// Convex hull of points (Andrew's monotone chain), counter-clockwise.
pub fn convex_hull(points: &[Pt]) -> Vec<Pt> {
    let mut pts = points.to_vec();
    pts.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    pts.dedup();
    if pts.len() < 3 {
        return pts;
    }
    let mut hull: Vec<Pt> = Vec::with_capacity(2 * pts.len());
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &Pt>> = if pass == 0 {
            Box::new(pts.iter())
        } else {
            Box::new(pts.iter().rev())
        };
        for &p in iter {
            while hull.len() >= start + 2
                && cross(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0.0
            {
                hull.pop();
            }
            hull.push(p);
        }
        hull.pop();
    }
    hull
}

/// False when the footprints' circumscribed circles do not touch (then every IoU is 0 and every
/// GIoU is <= 0).
pub fn may_overlap(a: &Detection, b: &Detection) -> bool {
    let (dx, dy) = (a.center[0] - b.center[0], a.center[1] - b.center[1]);
    let ra = 0.5 * a.size[0].hypot(a.size[1]);
    let rb = 0.5 * b.size[0].hypot(b.size[1]);
    dx * dx + dy * dy < (ra + rb) * (ra + rb)
}

/// The footprint's corners (counter-clockwise) relative to the point `o`.
fn footprint(d: &Detection, o: Pt) -> [Pt; 4] {
    let (s, c) = d.yaw.sin_cos();
    let (hl, hw) = (d.size[0] / 2.0, d.size[1] / 2.0);
    let (x, y) = (d.center[0] - o[0], d.center[1] - o[1]);
    [(hl, hw), (-hl, hw), (-hl, -hw), (hl, -hw)]
        .map(|(dx, dy)| [x + c * dx - s * dy, y + s * dx + c * dy])
}

/// Both footprints relative to `a`'s centre.
fn footprints(a: &Detection, b: &Detection) -> ([Pt; 4], [Pt; 4]) {
    let o = [a.center[0], a.center[1]];
    (footprint(a, o), footprint(b, o))
}

/// Area of the BEV intersection of two boxes' footprints.
pub fn bev_intersection(a: &Detection, b: &Detection) -> f64 {
    if !may_overlap(a, b) {
        return 0.0;
    }
    let (pa, pb) = footprints(a, b);
    polygon_area(&clip_convex(&pa, &pb)).max(0.0)
}

/// Bird's-eye-view IoU of two boxes.
pub fn bev_iou(a: &Detection, b: &Detection) -> f64 {
    let inter = bev_intersection(a, b);
    let union = a.size[0] * a.size[1] + b.size[0] * b.size[1] - inter;
    if union <= 0.0 {
        0.0
    } else {
        (inter / union).clamp(0.0, 1.0)
    }
}

fn z_range(d: &Detection) -> (f64, f64) {
    (d.center[2] - d.size[2] / 2.0, d.center[2] + d.size[2] / 2.0)
}

fn volume(d: &Detection) -> f64 {
    d.size[0] * d.size[1] * d.size[2]
}

/// Intersection volume, union volume of two rotated 3D boxes.
fn inter_union(a: &Detection, b: &Detection) -> (f64, f64) {
    let (a0, a1) = z_range(a);
    let (b0, b1) = z_range(b);
    let dz = (a1.min(b1) - a0.max(b0)).max(0.0);
    let inter = if dz > 0.0 {
        bev_intersection(a, b) * dz
    } else {
        0.0
    };
    (inter, volume(a) + volume(b) - inter)
}

/// 3D IoU of two rotated boxes.
pub fn iou_3d(a: &Detection, b: &Detection) -> f64 {
    let (inter, union) = inter_union(a, b);
    if union <= 0.0 {
        0.0
    } else {
        (inter / union).clamp(0.0, 1.0)
    }
}

/// 3D generalized IoU: IoU - (C - U) / C, C the enclosing volume (BEV hull area x z-extent).
pub fn giou_3d(a: &Detection, b: &Detection) -> f64 {
    let (inter, union) = inter_union(a, b);
    let (pa, pb) = footprints(a, b);
    let mut pts = pa.to_vec();
    pts.extend(pb);
    let hull_area = polygon_area(&convex_hull(&pts));
    let (a0, a1) = z_range(a);
    let (b0, b1) = z_range(b);
    let enclosing = hull_area * (a1.max(b1) - a0.min(b0));
    if union <= 0.0 || enclosing <= 0.0 {
        return 0.0;
    }
    let iou = inter / union;
    (iou - (enclosing - union) / enclosing).clamp(-1.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::f64::consts::FRAC_PI_4;
    use v2x_protocol::Uncertainty;

    fn bx(c: [f64; 3], s: [f64; 3], yaw: f64) -> Detection {
        Detection {
            center: c,
            size: s,
            yaw,
            score: 1.0,
            std: Uncertainty::uniform(1.0, 1.0, 1.0),
            id: 0,
            ..v2x_protocol::fixtures::car(0.0, 0.0, 1.0)
        }
    }

    fn close(a: f64, b: f64) {
        assert!((a - b).abs() < 1e-9, "{a} vs {b}");
    }

    #[test]
    fn far_from_the_map_origin_as_near_it() {
        // a square and itself turned 45 degrees (an octagon of 8 (sqrt 2 - 1)), and an oblique
        // pair: at UTM-scale coordinates the same figures as at the map origin
        let yaw = std::f64::consts::FRAC_PI_4;
        for (x, y) in [(0.0, 0.0), (512_345.678, 5_412_987.123)] {
            let a = bx([x, y, 0.0], [2.0, 2.0, 2.0], 0.0);
            let b = bx([x, y, 0.0], [2.0, 2.0, 2.0], yaw);
            let c = bx([x + 0.7, y - 0.3, 0.1], [4.0, 1.8, 1.5], 0.3);
            let near = (iou_3d(&a, &b), giou_3d(&a, &c), bev_iou(&b, &c));
            if x == 0.0 {
                close(
                    near.0,
                    (8.0 * (2f64.sqrt() - 1.0)) / (8.0 - 8.0 * (2f64.sqrt() - 1.0)),
                );
            }
            let at_origin = {
                let a0 = bx([0.0, 0.0, 0.0], [2.0, 2.0, 2.0], 0.0);
                let b0 = bx([0.0, 0.0, 0.0], [2.0, 2.0, 2.0], yaw);
                let c0 = bx([0.7, -0.3, 0.1], [4.0, 1.8, 1.5], 0.3);
                (iou_3d(&a0, &b0), giou_3d(&a0, &c0), bev_iou(&b0, &c0))
            };
            assert!(
                (near.0 - at_origin.0).abs() < 1e-12,
                "{near:?} {at_origin:?}"
            );
            assert!(
                (near.1 - at_origin.1).abs() < 1e-9,
                "{near:?} {at_origin:?}"
            );
            assert!(
                (near.2 - at_origin.2).abs() < 1e-9,
                "{near:?} {at_origin:?}"
            );
        }
    }

    #[test]
    fn identical_boxes() {
        let a = bx([1.0, 2.0, 0.5], [4.0, 2.0, 1.5], 0.7);
        close(iou_3d(&a, &a), 1.0);
        close(giou_3d(&a, &a), 1.0);
        close(bev_iou(&a, &a), 1.0);
    }

    #[test]
    fn disjoint_boxes() {
        let a = bx([0.0; 3], [2.0, 2.0, 2.0], 0.0);
        let b = bx([4.0, 0.0, 0.0], [2.0, 2.0, 2.0], 0.0);
        close(iou_3d(&a, &b), 0.0);
        // hull 6 x 2, height 2 -> C = 24, U = 16 -> GIoU = -8/24
        close(giou_3d(&a, &b), -1.0 / 3.0);
    }

    #[test]
    fn axis_aligned_overlap() {
        // 2x2x2 boxes shifted 1 m in x: inter 1*2*2 = 4, union 12 -> 1/3; hull 3x2x2 = 12
        let a = bx([0.0; 3], [2.0, 2.0, 2.0], 0.0);
        let b = bx([1.0, 0.0, 0.0], [2.0, 2.0, 2.0], 0.0);
        close(iou_3d(&a, &b), 1.0 / 3.0);
        close(giou_3d(&a, &b), 1.0 / 3.0);
        // shifted in x and y by 1: inter 1*1*2 = 2, union 14; hull area 9 - 2*0.5 = 8, C = 16
        let c = bx([1.0, 1.0, 0.0], [2.0, 2.0, 2.0], 0.0);
        close(iou_3d(&a, &c), 2.0 / 14.0);
        close(giou_3d(&a, &c), 2.0 / 14.0 - 2.0 / 16.0);
        close(bev_iou(&a, &c), 1.0 / 7.0);
    }

    #[test]
    fn rotated_square_octagon() {
        // unit... a 2x2 square and the same square rotated by 45 deg: a regular octagon of
        // area 8 (sqrt 2 - 1); union 8 - that.
        let a = bx([0.0; 3], [2.0, 2.0, 1.0], 0.0);
        let b = bx([0.0; 3], [2.0, 2.0, 1.0], FRAC_PI_4);
        let oct = 8.0 * (2f64.sqrt() - 1.0);
        close(bev_intersection(&a, &b), oct);
        close(iou_3d(&a, &b), oct / (8.0 - oct));
        close(bev_iou(&a, &b), oct / (8.0 - oct));
    }

    #[test]
    fn boxes_differing_in_height() {
        // same footprint 2x2; heights 2 (z in [-1, 1]) and 1 centred at 1.0 (z in [0.5, 1.5])
        let a = bx([0.0, 0.0, 0.0], [2.0, 2.0, 2.0], 0.0);
        let b = bx([0.0, 0.0, 1.0], [2.0, 2.0, 1.0], 0.0);
        // inter 4 * 0.5 = 2, union 8 + 4 - 2 = 10, C = 4 * 2.5 = 10
        close(iou_3d(&a, &b), 0.2);
        close(giou_3d(&a, &b), 0.2);
        close(bev_iou(&a, &b), 1.0);
    }

    proptest! {
        #[test]
        fn iou_bounds_and_symmetry(
            c1 in prop::array::uniform3(-3.0f64..3.0), s1 in prop::array::uniform3(0.2f64..5.0), y1 in -4.0f64..4.0,
            c2 in prop::array::uniform3(-3.0f64..3.0), s2 in prop::array::uniform3(0.2f64..5.0), y2 in -4.0f64..4.0,
        ) {
            let a = bx(c1, s1, y1);
            let b = bx(c2, s2, y2);
            let (i, g) = (iou_3d(&a, &b), giou_3d(&a, &b));
            prop_assert!((0.0..=1.0).contains(&i));
            prop_assert!((-1.0..=1.0).contains(&g));
            prop_assert!(g <= i + 1e-9);
            prop_assert!((i - iou_3d(&b, &a)).abs() < 1e-9);
            prop_assert!((g - giou_3d(&b, &a)).abs() < 1e-9);
            prop_assert!((bev_iou(&a, &b) - bev_iou(&b, &a)).abs() < 1e-9);
        }
    }
}
