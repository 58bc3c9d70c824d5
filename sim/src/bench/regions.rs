//! Tracks across regions (`bench regions --tracking`): each method's fused boxes tracked by
//! one fuser, by regional fusers that never hear each other, and by regional fusers handing
//! their tracks over at the borders ([`v2x_fuser::tracker::handover`]); and the same with each
//! agent's boxes through the tracks. The identity switches the borders add are the regional rows'
//! less the one fuser's.

use crate::bench::fusers::Fusers;
use crate::bench::{
    agent_detections, in_order, merge_pairs, scenes, score_tracked, BenchConfig, Scope, Scored,
    TrackingRow,
};
use crate::dataset::GroundTruth;
use crate::metrics::Accumulator;
use crate::noise::NoiseSetting;
use crate::tracking_eval::TrackingEval;
use rayon::prelude::*;
use v2x_fuser::intake::region::Tiling;
use v2x_fuser::tracker::handover::RegionalTrackers;
use v2x_fuser::tracker::{Tracker, TrackerParams};
use v2x_fuser::Method;

/// The ways a method's boxes are tracked, each a row: (guided, who tracks).
const WAYS: [(bool, Scope); 6] = [
    (false, Scope::One),
    (false, Scope::Regions),
    (false, Scope::HandOver),
    (true, Scope::One),
    (true, Scope::Regions),
    (true, Scope::HandOver),
];

/// A tracker of one way: one fuser's, or a city of regional fusers'.
enum Way {
    One(Tracker),
    Regions(RegionalTrackers),
}

/// The rows: under each setting, per method (the oracle gt-wls but guided) each way of
/// [`WAYS`], scored as `bench tracking` scores its tracked rows; the trackers `params`'s
/// (`soft` for the tracked ways only).
pub fn run_region_tracking(
    gt: &GroundTruth,
    cfg: &BenchConfig,
    tiling: Tiling,
    halo_m: f64,
    params: TrackerParams,
) -> Vec<TrackingRow> {
    let mut rows = Vec::new();
    let names: Vec<(usize, Scored)> = cfg
        .methods
        .iter()
        .enumerate()
        .flat_map(|(m, &method)| {
            WAYS.iter()
                .enumerate()
                .filter(move |(_, (guided, _))| !guided || method != Method::GtWls)
                .map(move |(k, &(guided, scope))| {
                    let scored = Scored::Tracks {
                        method,
                        guided,
                        scope,
                    };
                    (m * WAYS.len() + k, scored)
                })
        })
        .collect();
    let slots = cfg.methods.len() * WAYS.len();
    for setting in &cfg.settings {
        let empty = || {
            (
                vec![Accumulator::new(); slots],
                vec![TrackingEval::new(); slots],
            )
        };
        let (accs, evals) = in_order(
            scenes(gt).into_par_iter(),
            |frames| scene(gt, &frames, setting, cfg, (tiling, halo_m), params),
            merge_pairs,
        )
        .unwrap_or_else(empty);
        for (slot, method) in &names {
            rows.push(TrackingRow {
                noise: setting.name.clone(),
                method: *method,
                metrics: accs[*slot].summary(),
                tracking: Some(evals[*slot].summary()),
            });
        }
    }
    rows
}

/// One scene: every way of every method, frame by frame.
fn scene(
    gt: &GroundTruth,
    frames: &[usize],
    setting: &NoiseSetting,
    cfg: &BenchConfig,
    (tiling, halo_m): (Tiling, f64),
    base: TrackerParams,
) -> (Vec<Accumulator>, Vec<TrackingEval>) {
    let slots = cfg.methods.len() * WAYS.len();
    let mut accs = vec![Accumulator::new(); slots];
    let mut evals = vec![TrackingEval::new(); slots];
    // Every class is tracked, so that the detection columns compare with `bench tracking`'s.
    let mut ways: Vec<Way> = (0..slots)
        .map(|slot| {
            let (guided, scope) = WAYS[slot % WAYS.len()];
            let mut params = base.with_guided(guided);
            params.management.all_classes = true;
            let regions = |handover| RegionalTrackers::new(tiling, halo_m, params, handover);
            match scope {
                Scope::One => Way::One(Tracker::new(params)),
                Scope::Regions => Way::Regions(regions(false)),
                Scope::HandOver => Way::Regions(regions(true)),
            }
        })
        .collect();
    // Each method's pipeline, without history, fuses for one fuser and for every region.
    let mut fusers = Fusers::new(&cfg.methods, setting.agents.len(), None);
    let scene = gt.frames[frames[0]].scene;
    for &i in frames {
        let f = &gt.frames[i];
        let dets = agent_detections(gt, i, setting, cfg.seed, cfg.range);
        for (slot, way) in ways.iter_mut().enumerate() {
            let m = slot / WAYS.len();
            let method = &cfg.methods[m];
            let (guided, _) = WAYS[slot % WAYS.len()];
            if guided && *method == Method::GtWls {
                continue;
            }
            let t = f.timestamp_us;
            let out = match way {
                Way::One(tr) if guided => tr.step_agents(t, &dets, method),
                Way::One(tr) => tr.step(t, &fusers.fuse(m, t, &dets)),
                Way::Regions(r) => r.step(t, &dets, method, |input| fusers.fuse(m, t, input)),
            };
            score_tracked(&mut accs[slot], &mut evals[slot], scene, f, out);
        }
    }
    (accs, evals)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::table::Rows;

    #[test]
    fn handed_over_tracks_switch_as_one_fusers_and_regions_alone_switch_at_borders() {
        // Two town scenes of 6 s at 10 Hz, in tiles of 50 m: many objects cross a border.
        let (gt, cfg) = crate::bench::tracking_case(&["csba-wls+", "gt-wls"], "moderate");
        let tiling = Tiling::new(50.0).unwrap();
        for soft in [false, true] {
            let params = TrackerParams::with_mode(if soft {
                v2x_fuser::tracker::Association::Soft
            } else {
                v2x_fuser::tracker::Association::Assignment
            });
            let rows = run_region_tracking(&gt, &cfg, tiling, 30.0, params);
            let names: Vec<String> = rows.iter().map(|r| r.method.to_string()).collect();
            assert_eq!(
                names,
                [
                    "csba-wls+ tracked",
                    "csba-wls+ tracked regions",
                    "csba-wls+ tracked regions hand-over",
                    "csba-wls+ guided",
                    "csba-wls+ guided regions",
                    "csba-wls+ guided regions hand-over",
                    "gt-wls tracked",
                    "gt-wls tracked regions",
                    "gt-wls tracked regions hand-over",
                ]
            );
            let ids: Vec<usize> = rows
                .iter()
                .map(|r| r.tracking.as_ref().unwrap().ids)
                .collect();
            assert!(rows[..]
                .table()
                .contains("| moderate | gt-wls tracked regions hand-over |"));
            for way in [0, 3, 6] {
                let (one, alone, handed) = (ids[way], ids[way + 1], ids[way + 2]);
                // Here 8 switches at the borders, 0 handed over, 0 by one fuser.
                assert!(alone >= one + 5, "soft {soft}: {names:?} {ids:?}");
                assert!(handed <= one + 2, "soft {soft}: {names:?} {ids:?}");
            }
        }
    }
}
