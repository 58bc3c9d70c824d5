//! Association through the tracks (`docs/method.md` §8.1): the tracks' predictions take part in
//! the association between agents as its first list, so that each agent's boxes meet the
//! tracks, tighter than any box, before they meet each other.
//!
//! Per window at time t, with the agents' boxes already brought to t:
//! 1. **predict** every track to t, as [`Tracker::step`] does, and write each as a box: its
//!    centre with the predicted covariance P, its size and yaw with their variances;
//! 2. **associate** with CSBA-3D (the fallback method's parameters; csba-wls+'s for a method
//!    that is not CSBA-3D) over the lists [predictions, agent 1, agent 2, ...]: sequentially, so
//!    agent 1's boxes are paired with the predictions, agent 2's with the predictions as agent
//!    1's boxes have updated them, and so on;
//! 3. **update** each track whose prediction is in a group with the group's boxes, one after
//!    another (Kalman, Joseph form): for independent errors, the update with WLS-3D of the
//!    boxes. A box beyond the tracker's gate is another object's (taken by the largest
//!    matching where the track's object went unseen): in a second pass it, and every box of a
//!    group without a prediction, goes to the likeliest track within the gate that has no box
//!    of its agent yet; a turned-away box no track takes goes unused. A track takes its object
//!    id from its surest box, as WLS-3D does. A group without a prediction none of whose boxes a
//!    track took is a new object: its fused box starts a tentative track;
//! 4. **lifecycle** as [`Tracker::step`]: a track whose group holds a box counts as hit.

use super::{distance, estimate, update, Tracked, Tracker};
use crate::maths::association::{assign, CsbaParams, Edge};
use crate::maths::method::csba_groups;
use crate::Method;
use v2x_protocol::Detection;

impl Tracker {
    /// Steps the tracks to the window at `t_us` with each agent's boxes (`agents[k]`; boxes of
    /// classes not tracked are passed over), associating them with the tracks' predictions and
    /// with each other by CSBA-3D with `fallback`'s parameters; returns the confirmed tracks it
    /// updated.
    pub fn step_agents(
        &mut self,
        t_us: u64,
        agents: &[Vec<Detection>],
        fallback: &Method,
    ) -> Vec<Tracked> {
        // 1. predict
        let dt = self.advance(t_us);
        let params = fallback.csba_params().unwrap_or(CsbaParams::PLUS);
        let mut lists: Vec<Vec<Detection>> = Vec::with_capacity(agents.len() + 1);
        lists.push(self.tracks.iter().map(estimate).collect());
        lists.extend(
            agents
                .iter()
                .map(|a| self.tracked_classes(a).1.into_owned()),
        );
        // 2. associate
        let (fused, groups) = csba_groups(&params, &lists);
        // 3. update, or a new object
        let n_agents = lists.len() - 1;
        let mut hit = vec![false; self.tracks.len()];
        // Per track: the agents whose box it took, and its surest box (variance, object id).
        let mut took = vec![vec![false; n_agents]; self.tracks.len()];
        let mut surest: Vec<Option<(f64, u32)>> = vec![None; self.tracks.len()];
        // Per agent: the boxes no group's track took, and whether a track took each box.
        let mut left: Vec<Vec<usize>> = vec![Vec::new(); n_agents];
        let mut used: Vec<Vec<bool>> = lists[1..].iter().map(|l| vec![false; l.len()]).collect();
        let mut new = Vec::new();
        for (f, members) in fused.into_iter().zip(groups) {
            let Some(&(_, i)) = members.iter().find(|(k, _)| *k == 0) else {
                for &(k, j) in &members {
                    left[k - 1].push(j);
                }
                new.push((f, members));
                continue;
            };
            for &(k, j) in members.iter().filter(|(k, _)| *k != 0) {
                let b = &lists[k][j];
                // CSBA-3D's gate is the looser, and its matching the largest: a box beyond the
                // tracker's own gate is another object's, and waits for the second pass.
                if distance(&self.tracks[i], b)
                    .is_none_or(|(d2, _)| d2 > self.params.association.gate)
                {
                    left[k - 1].push(j);
                    continue;
                }
                self.take(i, b, dt, &mut hit, &mut surest);
                took[i][k - 1] = true;
                used[k - 1][j] = true;
            }
        }
        let mut taken = Taken {
            hit: &mut hit,
            surest: &mut surest,
            used: &mut used,
        };
        self.second_pass(&lists[1..], &left, &took, dt, &mut taken);
        // The object id (simulation) of the surest box, as WLS-3D keeps it.
        for (t, s) in self.tracks.iter_mut().zip(surest) {
            if let Some((_, id)) = s {
                t.truth = id;
            }
        }
        // 4. lifecycle; a new group none of whose boxes a track took starts a track.
        let mut out = self.lifecycle(&hit);
        for (b, members) in &new {
            if !members.iter().any(|&(k, j)| used[k - 1][j]) {
                out.extend(self.birth(b));
            }
        }
        out
    }
}

/// What step 3 has given so far: which tracks were hit, each track's surest box (variance,
/// object id), and per agent which boxes a track took.
struct Taken<'a> {
    hit: &'a mut [bool],
    surest: &'a mut [Option<(f64, u32)>],
    used: &'a mut [Vec<bool>],
}

impl Tracker {
    /// Step 3's second pass: each box no group's track took (`left[a]`, indices into
    /// `agents[a]`: turned away, or in a group without a track) goes to the likeliest track
    /// within the gate that has no box of its agent yet (`took[i][a]`), as [`Tracker::step`]
    /// would give it.
    fn second_pass(
        &mut self,
        agents: &[Vec<Detection>],
        left: &[Vec<usize>],
        took: &[Vec<bool>],
        dt: f64,
        taken: &mut Taken,
    ) {
        for (a, boxes) in left.iter().enumerate() {
            let mut edges = Vec::new();
            for (i, t) in self.tracks.iter().enumerate() {
                for (n, &j) in boxes.iter().enumerate() {
                    let b = &agents[a][j];
                    if took[i][a] || b.class != t.class {
                        continue;
                    }
                    if let Some((d2, ln_det)) =
                        distance(t, b).filter(|d| d.0 <= self.params.association.gate)
                    {
                        edges.push(Edge::new(i, n, d2 + ln_det));
                    }
                }
            }
            for (i, n) in assign(self.tracks.len(), boxes.len(), &edges) {
                self.take(i, &agents[a][boxes[n]], dt, taken.hit, taken.surest);
                taken.used[a][boxes[n]] = true;
            }
        }
    }

    /// Track `i` takes box `b`: a Kalman update, the window's process noise with its first box.
    fn take(
        &mut self,
        i: usize,
        b: &Detection,
        dt: f64,
        hit: &mut [bool],
        surest: &mut [Option<(f64, u32)>],
    ) {
        update(
            &mut self.tracks[i],
            b,
            if hit[i] { 0.0 } else { dt },
            &self.params.motion,
        );
        hit[i] = true;
        let v = b.total_variance();
        if surest[i].is_none_or(|(s, _)| v < s) {
            surest[i] = Some((v, b.id));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tracker::TrackerParams;
    use v2x_protocol::Uncertainty;

    /// A car at (x, y) with `std` m of position noise.
    fn car(x: f64, y: f64, std: f64) -> Detection {
        Detection {
            std: Uncertainty::uniform(std, 0.1, 0.1),
            ..crate::tracker::tests::car(x, y, 0.0)
        }
    }

    fn method() -> Method {
        "csba-wls+".parse().unwrap()
    }

    #[test]
    fn sequential_updates_equal_one_update_with_the_fused_box() {
        // A track, then a window with two agents' boxes of its car: updating with one agent
        // after the other gives the state of fusing them first (WLS-3D) and updating once.
        let params = TrackerParams::default();
        let start = [car(0.0, 0.0, 0.5)];
        let (a, b) = (car(1.2, 0.3, 0.5), car(0.7, -0.2, 1.5));
        let mut guided = Tracker::new(params);
        let mut fused = Tracker::new(params);
        guided.step(0, &start);
        fused.step(0, &start);
        let g = guided.step_agents(100_000, &[vec![a.clone()], vec![b.clone()]], &method());
        let f = fused.step(100_000, &method().fuse(&[vec![a], vec![b]]));
        assert_eq!((g.len(), f.len()), (1, 1));
        assert_eq!(g[0].tracking_id, f[0].tracking_id);
        for k in 0..2 {
            assert!(
                (g[0].det.center[k] - f[0].det.center[k]).abs() < 1e-9,
                "{g:?} {f:?}"
            );
            let (pg, pf) = (
                g[0].det.pos_cov.as_ref().unwrap(),
                f[0].det.pos_cov.as_ref().unwrap(),
            );
            assert!((pg[k][k] - pf[k][k]).abs() < 1e-9);
        }
    }

    /// Identity switches of each way over a dense, seeded scene: 14 cars in two lanes 3.5 m
    /// apart, 7 m between cars, at 10 and 12 m/s, seen by two agents at `std` m of noise for
    /// 8 s at 10 Hz; a switch is a car's track id changing from one window to the next.
    fn switches(std: f64, seed: u64) -> (usize, usize) {
        use rand::SeedableRng;
        use rand_distr::{Distribution, StandardNormal};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let params = TrackerParams::default();
        let (mut guided, mut fused) = (Tracker::new(params), Tracker::new(params));
        let (mut last_g, mut last_f) = (vec![None; 14], vec![None; 14]);
        let (mut sw_g, mut sw_f) = (0, 0);
        for k in 0..80u64 {
            let t = k as f64 * 0.1;
            let agents: Vec<Vec<Detection>> = (0..2)
                .map(|_| {
                    (0..14)
                        .map(|c| {
                            let lane = (c % 2) as f64;
                            let x = 7.0 * (c / 2) as f64 + (10.0 + 2.0 * lane) * t;
                            let mut g = || -> f64 { StandardNormal.sample(&mut rng) };
                            let mut b = car(x + std * g(), 3.5 * lane + std * g(), std);
                            b.id = c as u32;
                            b
                        })
                        .collect()
                })
                .collect();
            let count = |out: Vec<Tracked>, last: &mut Vec<Option<u32>>, sw: &mut usize| {
                for tr in out {
                    let c = tr.det.id as usize;
                    if last[c].is_some_and(|id| id != tr.tracking_id) {
                        *sw += 1;
                    }
                    last[c] = Some(tr.tracking_id);
                }
            };
            count(
                guided.step_agents(k * 100_000, &agents, &method()),
                &mut last_g,
                &mut sw_g,
            );
            count(
                fused.step(k * 100_000, &method().fuse(&agents)),
                &mut last_f,
                &mut sw_f,
            );
        }
        (sw_g, sw_f)
    }

    #[test]
    fn through_the_tracks_fewer_identities_switch_in_dense_noisy_traffic() {
        let (mut g, mut f) = (0, 0);
        for seed in 1..=4 {
            let (a, b) = switches(1.5, seed);
            g += a;
            f += b;
        }
        assert!(
            f >= 10,
            "the scene must be hard for fuse-then-track: {f} switches"
        );
        // Seeds 1-4: 291 switches through the tracks, 357 fusing first.
        assert!(
            10 * g <= 9 * f,
            "through the tracks {g} switches, fuse then track {f}"
        );
    }

    #[test]
    fn boxes_no_track_explains_are_fused_between_agents_into_one_new_track() {
        let mut tr = Tracker::new(TrackerParams::default());
        let a = vec![car(50.0, 0.0, 0.5)];
        let b = vec![car(50.4, 0.2, 0.5)];
        assert!(tr
            .step_agents(0, &[a.clone(), b.clone()], &method())
            .is_empty());
        let out = tr.step_agents(100_000, &[a, b], &method());
        assert_eq!(out.len(), 1, "one object, one track: {out:?}");
        assert_eq!(tr.stats().live, 1);
    }

    #[test]
    fn a_box_its_groups_track_turned_away_goes_to_a_track_without_its_agents_box() {
        let mut tr = Tracker::new(TrackerParams::default());
        tr.step(0, &[car(0.0, 0.0, 0.3), car(5.0, 0.0, 0.3)]);
        tr.step(100_000, &[car(0.0, 0.0, 0.3), car(5.0, 0.0, 0.3)]);
        let dt = tr.advance(200_000);
        // Agent 1's boxes near each track; track 0 took agent 1's box already.
        let agents = vec![vec![car(4.6, 0.0, 0.3), car(0.3, 0.0, 0.3)]];
        let took = vec![vec![true], vec![false]];
        let (mut hit, mut surest) = (vec![true, false], vec![None, None]);
        let mut used = vec![vec![false, false]];
        let mut taken = Taken {
            hit: &mut hit,
            surest: &mut surest,
            used: &mut used,
        };
        tr.second_pass(&agents, &[vec![0, 1]], &took, dt, &mut taken);
        assert_eq!(used, [[true, false]]);
        assert_eq!(hit, [true, true], "the box near track 1 went to it");
        assert!(tr.tracks[1].x[0] < 5.0 && tr.tracks[1].x[0] > 4.6);
        // The box near track 0 found no track: track 0 had agent 1's box, track 1 is too far.
        assert_eq!(tr.tracks[0].x[0], 0.0);
        assert!(surest[0].is_none() && surest[1].is_some());
    }
}
