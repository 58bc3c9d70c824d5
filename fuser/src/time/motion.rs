//! Motion compensation, sans-IO: every detection of a window is predicted to the window's
//! reference time t_ref before association and fusion, so that boxes captured at different
//! instants are compared where their objects are at t_ref, not where they were.
//!
//! t_ref is the latest capture time in the window: the fused output describes the world as of
//! the newest information, and older frames are carried forward. Constant velocity over
//! dt = t_ref - t_capture:
//!
//! - centre: p' = p + v dt (x and y; z is kept);
//! - centre covariance: P' = P + S_v dt^2 + Q, with S_v the velocity covariance and
//!   Q = sigma_a^2 dt^4 / 4 per axis, the position variance a white acceleration of std sigma_a
//!   adds over dt;
//! - velocity covariance: S_v' = S_v + sigma_a^2 dt^2.
//!
//! A detection without a velocity cannot be moved: its centre is kept and its x-y variance grows
//! by (v_max dt)^2 / 3, the variance of a displacement at a speed uniform in [-v_max, v_max].

use v2x_protocol::Detection;

/// Parameters of the motion model.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct MotionParams {
    /// Std of the unmodelled acceleration sigma_a (m/s^2).
    pub accel_std: f64,
    /// Speed bound v_max for detections without a velocity (m/s).
    pub speed_bound: f64,
    /// Seconds of motion per second of capture clock: 1 live; a replay at speed s stamps its
    /// frames in wall time, s times slower than the data, so s.
    pub time_scale: f64,
}

impl Default for MotionParams {
    /// sigma_a = 2 m/s^2 (urban driving: braking and turning rarely exceed it over 0.1 s) and
    /// v_max = 15 m/s (54 km/h, an urban speed limit).
    fn default() -> Self {
        MotionParams {
            accel_std: 2.0,
            speed_bound: 15.0,
            time_scale: 1.0,
        }
    }
}

/// The x-y variance a detection gains when carried over `dt_s` seconds:
/// (S_v,x dt^2 + Q, S_v,y dt^2 + Q) with a velocity, ((v_max dt)^2 / 3, same) without.
pub fn added_variance(d: &Detection, dt_s: f64, p: &MotionParams) -> [f64; 2] {
    let dt2 = dt_s * dt_s;
    match &d.velocity {
        Some(v) => {
            let q = p.accel_std * p.accel_std * dt2 * dt2 / 4.0;
            [v.std[0] * v.std[0] * dt2 + q, v.std[1] * v.std[1] * dt2 + q]
        }
        None => {
            let u = (p.speed_bound * dt_s).powi(2) / 3.0;
            [u, u]
        }
    }
}

/// A detection predicted `dt_s` seconds ahead (negative: back).
pub fn predict(d: &Detection, dt_s: f64, p: &MotionParams) -> Detection {
    let mut out = d.clone();
    predict_in_place(&mut out, dt_s, p);
    out
}

/// [`predict`] in place.
pub fn predict_in_place(d: &mut Detection, dt_s: f64, p: &MotionParams) {
    if dt_s == 0.0 {
        return;
    }
    let add = added_variance(d, dt_s, p);
    if let Some(v) = &mut d.velocity {
        for k in 0..2 {
            d.center[k] += v.v[k] * dt_s;
            v.std[k] = (v.std[k] * v.std[k] + (p.accel_std * dt_s).powi(2)).sqrt();
        }
    }
    match &mut d.pos_cov {
        Some(c) => {
            c[0][0] += add[0];
            c[1][1] += add[1];
            d.std.pos[0] = c[0][0].sqrt();
            d.std.pos[1] = c[1][1].sqrt();
        }
        None => {
            for k in 0..2 {
                d.std.pos[k] = (d.std.pos[k] * d.std.pos[k] + add[k]).sqrt();
            }
        }
    }
}

/// A closed window's reference time t_ref (its latest capture) and its frames' detections in
/// agent order, taken from the window and predicted to t_ref with `motion` (as captured
/// without).
pub fn align_window(
    closed: crate::time::window::Closed,
    motion: Option<&MotionParams>,
) -> (u64, Vec<Vec<Detection>>) {
    let t_ref = closed
        .frames
        .values()
        .map(|f| f.capture_us)
        .max()
        .unwrap_or(closed.anchor_us);
    let lists = closed
        .frames
        .into_values()
        .map(|f| {
            let mut dets = f.detections;
            if let Some(p) = motion {
                let dt = seconds_to(t_ref, f.capture_us, p);
                for d in &mut dets {
                    predict_in_place(d, dt, p);
                }
            }
            dets
        })
        .collect();
    (t_ref, lists)
}

/// The motion's seconds from a capture at `t_us` to `t_ref_us` (at the replay's time scale).
fn seconds_to(t_ref_us: u64, t_us: u64, p: &MotionParams) -> f64 {
    (t_ref_us as f64 - t_us as f64) / 1e6 * p.time_scale
}

#[cfg(test)]
mod tests {
    use super::*;
    use v2x_protocol::{Uncertainty, Velocity};

    fn moving() -> Detection {
        Detection {
            center: [10.0, 5.0, 1.0],
            std: Uncertainty::uniform(0.5, 0.1, 0.1),
            velocity: Some(Velocity {
                v: [15.0, -2.0],
                std: [0.3, 0.4],
            }),
            ..Default::default()
        }
    }

    #[test]
    fn a_moving_box_is_carried_to_t_ref() {
        let p = MotionParams::default();
        let d = predict(&moving(), 0.05, &p);
        // 15 m/s x 50 ms = 0.75 m; -2 m/s x 50 ms = -0.1 m; z kept
        assert!((d.center[0] - 10.75).abs() < 1e-12);
        assert!((d.center[1] - 4.9).abs() < 1e-12);
        assert_eq!(d.center[2], 1.0);
        // var x: 0.25 + 0.09 x 0.0025 + 4 x 0.05^4 / 4 = 0.25 + 0.000225 + 0.00000625
        assert!((d.std.pos[0].powi(2) - 0.25023125).abs() < 1e-12);
        // var y: 0.25 + 0.16 x 0.0025 + 0.00000625
        assert!((d.std.pos[1].powi(2) - 0.25040625).abs() < 1e-12);
        assert_eq!(d.std.pos[2], 0.5);
        // velocity std: sqrt(0.09 + (2 x 0.05)^2) = sqrt(0.1)
        assert!((d.velocity.unwrap().std[0] - 0.1f64.sqrt()).abs() < 1e-12);
        // and back again to where it was
        let back = predict(&d, -0.05, &p);
        assert!((back.center[0] - 10.0).abs() < 1e-12);
    }

    #[test]
    fn without_velocity_only_the_variance_grows() {
        let mut d = moving();
        d.velocity = None;
        let q = predict(&d, 0.1, &MotionParams::default());
        assert_eq!(q.center, d.center);
        // (15 x 0.1)^2 / 3 = 0.75
        assert!((q.std.pos[0].powi(2) - (0.25 + 0.75)).abs() < 1e-12);
        // a full covariance grows on its diagonal
        d.pos_cov = Some(Box::new([
            [0.25, 0.1, 0.0],
            [0.1, 0.25, 0.0],
            [0.0, 0.0, 0.25],
        ]));
        let q = predict(&d, 0.1, &MotionParams::default());
        let c = q.pos_cov.unwrap();
        assert!((c[0][0] - 1.0).abs() < 1e-12 && c[0][1] == 0.1 && c[2][2] == 0.25);
    }

    #[test]
    fn a_window_is_compensated_from_each_frames_own_capture_time_to_its_latest() {
        let frame = |agent: &str, capture_us: u64| v2x_protocol::Frame {
            agent: agent.into(),
            kind: v2x_protocol::AgentKind::Vehicle,
            seq: 0,
            capture_us,
            origin: [0.0; 3],
            detections: vec![moving()],
        };
        let closed =
            crate::time::window::Closed::of([frame("a", 1_000_000), frame("b", 1_100_000)]);
        let (t_ref, out) = align_window(closed.clone(), Some(&Default::default()));
        assert_eq!(t_ref, 1_100_000);
        assert!(
            (out[0][0].center[0] - 11.5).abs() < 1e-9,
            "100 ms at 15 m/s"
        );
        assert_eq!(out[1][0].center[0], 10.0, "already at t_ref");
        // Without motion, as captured.
        let (_, raw) = align_window(closed, None);
        assert_eq!(raw[0][0].center[0], 10.0);
    }
}
