//! The fusion worker: closed windows come in through a bounded queue, are fused on a blocking
//! thread (so a heavy window never stalls the receive loop), brought into the wire's domain,
//! encoded and published on `v2x/NS/fused`, in the order they closed; with tracking on, the
//! tracks the window updated follow on `v2x/NS/tracks`. Each outcome goes back to the receive
//! loop, which keeps the statistics.

use super::{Clock, Fused};
use crate::intake::region::Scope;
use crate::pipeline::{Pipeline, Prepared, Reference, Steps};
use crate::time::window::Closed;
use crate::tracker::handover::{id_block, published, step_region, Handover};
use crate::tracker::{TrackStats, Tracker, TrackerParams};
use crate::uncertainty::detector::DetectorParams;
use crate::Method;
use tokio::sync::mpsc;
use v2x_protocol::wire::{self, Fit};
use v2x_protocol::{AgentKind, Detection, Frame, Provenance};

/// A closed window to fuse.
pub(super) struct Job {
    pub closed: Closed,
    /// When it closed (fuser clock, us).
    pub closed_at_us: u64,
}

/// What became of a job.
pub(super) struct Done {
    pub fused: Fused,
    pub fit: Fit,
    /// The tracker's counters after this window, when the node tracks.
    pub tracks: Option<TrackStats>,
    /// Why it was not published, if it was not.
    pub error: Option<String>,
    /// How often the association's bounds applied in this window (capped, greedy).
    pub degraded: (u64, u64),
    pub closed_at_us: u64,
    pub done_at_us: u64,
}

/// Fuses one closed window into the frame the fuser publishes (not yet fitted to the wire),
/// stamped with the window's reference time, its latest capture, through the `pipeline`
/// (`crate::pipeline`); also returns each agent's boxes as the pipeline prepared them.
pub fn fuse_window(
    pipeline: &mut Pipeline,
    closed: Closed,
    seq: u32,
) -> (Fused, Vec<Vec<Detection>>) {
    let complete = closed.complete;
    let prepared = pipeline.prepare(closed);
    let learned = pipeline.learned();
    let (detections, sources) = pipeline
        .steps()
        .fuse(&prepared.lists, prepared.receiver)
        .into_iter()
        .map(|s| (s.det, s.sources))
        .unzip();
    let Prepared {
        t_ref,
        agents,
        lists,
        registration,
        ..
    } = prepared;
    let registration = agents
        .iter()
        .zip(registration)
        .filter_map(|(name, r)| Some((name.clone(), r?)))
        .collect();
    let fused = Fused {
        frame: Frame {
            agent: "fuser".into(),
            kind: AgentKind::Infrastructure,
            seq,
            capture_us: t_ref,
            origin: [0.0; 3],
            detections,
        },
        provenance: Provenance {
            agents,
            complete,
            sources,
        },
        tracks: None,
        registration,
        learned,
    };
    (fused, lists)
}

/// Keeps the fused boxes `keep` says, with their sources.
fn keep_fused(fused: &mut Fused, keep: impl Fn(&Detection) -> bool) {
    let dets = std::mem::take(&mut fused.frame.detections);
    let sources = std::mem::take(&mut fused.provenance.sources);
    let has_sources = sources.len() == dets.len();
    let mut sources = sources.into_iter();
    for d in dets {
        let s = if has_sources { sources.next() } else { None };
        if keep(&d) {
            fused.frame.detections.push(d);
            fused.provenance.sources.extend(s);
        }
    }
}

/// How the worker fuses: the pipeline's steps, tracking and the region.
#[derive(Clone, Debug)]
pub(super) struct Fusion {
    pub steps: Steps,
    pub track: Option<TrackerParams>,
    pub scope: Scope,
    /// A tracking regional fuser's neighbours' tracks, as heard.
    pub heard: Option<super::handover::Heard>,
}

/// What the worker carries from window to window (`None` while a job has it).
struct Carried {
    pipeline: Option<Pipeline>,
    tracker: Option<Tracker>,
    handover: Option<Handover>,
}

impl Fusion {
    /// A pipeline without history: registration to the infrastructure, the agents' own stds;
    /// when a detector's tail goes to the tracks ([`Fusion::tail_for_tracks`]), it keeps it.
    fn pipeline(&self) -> Pipeline {
        let mut steps = self.steps.clone();
        if self.tail_for_tracks().is_some() {
            steps.detector = steps.detector.map(DetectorParams::for_tracking);
        }
        Pipeline::new(steps, Reference::Infrastructure, None)
    }

    /// With tracking and a detector that drops its tail below an operating point: that point.
    /// The tracks then take every fused box, as `v2x-fuser track` gives them (the tracks'
    /// own operating point decides which are shown), and the fused frame drops the tail.
    fn tail_for_tracks(&self) -> Option<f64> {
        let min_score = self.track.and(self.steps.detector.as_ref())?.min_score;
        (min_score > 0.0).then_some(min_score)
    }

    fn fresh(&self) -> Carried {
        // A region's tracks take ids of its tile's own block, so no two regions give one id.
        let tracker = self.track.map(|p| match self.scope.tile() {
            Some(tile) => Tracker::with_ids(p, id_block(tile)),
            None => Tracker::new(p),
        });
        Carried {
            pipeline: Some(self.pipeline()),
            tracker,
            handover: self
                .track
                .and(self.scope.region().copied())
                .map(Handover::new),
        }
    }
}

/// The tracks frame of a fused window: the confirmed tracks it updated (fed the fused boxes of
/// the region's tile and halo, or with `guided` each agent's `lists` through the tracks, `method`
/// fusing the rest), those a `region` owns, each box's id its `tracking_id`, brought into the
/// wire's domain.
fn tracks_frame(
    tracker: &mut Tracker,
    fused: &Frame,
    lists: &[Vec<Detection>],
    method: &Method,
    region: Option<&crate::intake::region::Region>,
) -> Frame {
    let tracked = step_region(
        tracker,
        region,
        fused.capture_us,
        &fused.detections,
        lists,
        method,
    );
    let mut frame = Frame {
        agent: fused.agent.clone(),
        kind: fused.kind,
        seq: fused.seq,
        capture_us: fused.capture_us,
        origin: fused.origin,
        detections: published(&tracked),
    };
    wire::fit(&mut frame);
    frame
}

/// What fusing one job gives: the fused window, how it was fitted, its bytes, the tracks frame's
/// bytes with the tracker's counters, and the state carried to the next job.
type JobOutput = (
    Fused,
    Fit,
    Result<Vec<u8>, wire::EncodeError>,
    Option<(Result<Vec<u8>, wire::EncodeError>, TrackStats)>,
    Carried,
    (u64, u64),
);

/// Fuses one closed window on a blocking thread: the calibrated models, the learned stds,
/// fusion, the detector's tail and the region's share dropped, the wire's domain, then the
/// tracks (fed, in a region, every fused box of its tile and halo after its neighbours' ids,
/// and the detector's tail, in the wire's domain).
fn fuse_job(f: &Fusion, mut state: Carried, closed: Closed, seq: u32) -> JobOutput {
    // The association's bounds counted on this thread, for this window alone.
    let bounds_before = crate::maths::association::bounds_applied();
    let pipeline = state.pipeline.get_or_insert_with(|| f.pipeline());
    let (mut fused, lists) = fuse_window(pipeline, closed, seq);
    // The tracks' input when it is not the published frame: every fused box of a region's
    // tile and halo, and with a detector's tail dropped from the frame, the tail too.
    let mut untrimmed = None;
    let tail = f.tail_for_tracks();
    if state.tracker.is_some() && (f.scope != Scope::Whole || tail.is_some()) {
        let mut all = fused.frame.clone();
        wire::fit(&mut all);
        untrimmed = Some(all);
    }
    if let Some(min_score) = tail {
        keep_fused(&mut fused, |d| d.score >= min_score);
    }
    if f.scope != Scope::Whole {
        keep_fused(&mut fused, |d| f.scope.owns(d));
    }
    let fit = wire::fit_with(&mut fused.frame, Some(&mut fused.provenance));
    let bytes = wire::encode_with(&fused.frame, Some(&fused.provenance));
    let tracked = state.tracker.as_mut().map(|t| {
        if let (Some(h), Some(heard)) = (state.handover.as_mut(), &f.heard) {
            for (tile, t_us, tracks) in super::handover::drain(heard) {
                h.hear(tile, t_us, tracks);
            }
            h.adopt(t);
        }
        let input = untrimmed.as_ref().unwrap_or(&fused.frame);
        let frame = tracks_frame(t, input, &lists, &f.steps.method, f.scope.region());
        let bytes = wire::encode(&frame);
        fused.tracks = Some(frame.detections);
        (bytes, t.stats())
    });
    let after = crate::maths::association::bounds_applied();
    let degraded = (after.0 - bounds_before.0, after.1 - bounds_before.1);
    (fused, fit, bytes, tracked, state, degraded)
}

/// The empty window reported in place of one whose fusion panicked.
fn lost_window(seq: u32, anchor_us: u64, agents: Vec<String>, complete: bool) -> Fused {
    Fused {
        frame: Frame {
            agent: "fuser".into(),
            kind: AgentKind::Infrastructure,
            seq,
            capture_us: anchor_us,
            origin: [0.0; 3],
            detections: Vec::new(),
        },
        provenance: Provenance {
            agents,
            complete,
            sources: Vec::new(),
        },
        tracks: None,
        registration: Default::default(),
        learned: Default::default(),
    }
}

/// Runs the worker until its queue closes; with `tracks`, tracks go out on it after each
/// fused window.
pub(super) async fn run(
    fusion: Fusion,
    publisher: zenoh::pubsub::Publisher<'static>,
    tracks: Option<zenoh::pubsub::Publisher<'static>>,
    clock: Clock,
    mut jobs: mpsc::Receiver<Job>,
    done: mpsc::UnboundedSender<Done>,
) {
    let mut seq = 0u32;
    let mut carried = fusion.fresh();
    while let Some(job) = jobs.recv().await {
        let Job {
            closed,
            closed_at_us,
        } = job;
        let this_seq = seq;
        seq = seq.wrapping_add(1);
        let (anchor, agents, complete) = (
            closed.anchor_us,
            closed.frames.keys().cloned().collect::<Vec<_>>(),
            closed.complete,
        );
        let state = std::mem::replace(
            &mut carried,
            Carried {
                pipeline: None,
                tracker: None,
                handover: None,
            },
        );
        let f = fusion.clone();
        let work = tokio::task::spawn_blocking(move || fuse_job(&f, state, closed, this_seq)).await;
        // A fusion that panicked took the aligner and the tracks with it: start afresh.
        let (work, tracked, degraded) = match work {
            Ok((fused, fit, bytes, tracked, state, degraded)) => {
                carried = state;
                (Ok((fused, fit, bytes)), tracked, degraded)
            }
            Err(e) => {
                carried = fusion.fresh();
                (Err(e), None, (0, 0))
            }
        };
        let mut track_stats = None;
        if let (Some(p), Some((Ok(bytes), stats))) = (&tracks, tracked) {
            // A lost tracks frame is not a lost window: the next one carries the tracks on.
            let _ = p.put(bytes).await;
            track_stats = Some(stats);
        }
        let (fused, fit, error) = match work {
            Ok((fused, fit, Ok(bytes))) => {
                let error = publisher.put(bytes).await.err().map(|e| e.to_string());
                (fused, fit, error)
            }
            Ok((fused, fit, Err(e))) => (fused, fit, Some(format!("does not encode: {e}"))),
            // The fusion panicked: the window is lost (and counted), the worker goes on.
            Err(e) => (
                lost_window(this_seq, anchor, agents, complete),
                Fit::default(),
                Some(format!("fusion failed: {e}")),
            ),
        };
        let outcome = Done {
            fused,
            fit,
            tracks: track_stats,
            error,
            degraded,
            closed_at_us,
            done_at_us: clock.now_us(),
        };
        if done.send(outcome).is_err() {
            break;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One agent's window at `t_us` with a car at `score`.
    fn window(t_us: u64, score: f64) -> Closed {
        let frame = Frame {
            agent: "veh".into(),
            kind: AgentKind::Vehicle,
            seq: 0,
            capture_us: t_us,
            origin: [0.0; 3],
            detections: vec![Detection {
                score,
                ..v2x_protocol::fixtures::car(10.0, 0.0, 0.3)
            }],
        };
        Closed::of([frame])
    }

    #[test]
    fn a_detectors_tail_is_dropped_from_the_frame_but_reaches_the_tracks() {
        // A detector that shows boxes from 0.4, its groups scored by their members' scores.
        let detector = DetectorParams {
            min_score: 0.4,
            existence: None,
            ..Default::default()
        };
        let fusion = |track: bool| Fusion {
            steps: Steps {
                detector: Some(detector),
                ..Steps::method(Method::default())
            },
            track: track.then(|| detector.tracker(TrackerParams::default())),
            scope: Scope::Whole,
            heard: None,
        };
        // A car seen at 0.3 only: below the operating point in every window.
        for track in [false, true] {
            let f = fusion(track);
            let mut state = f.fresh();
            let mut births = 0;
            for k in 0..4u64 {
                let (fused, _, _, tracked, next, _) =
                    fuse_job(&f, state, window(k * 100_000, 0.3), 0);
                state = next;
                // The published frame drops it either way, and no track of it is shown.
                assert!(fused.frame.detections.is_empty(), "{:?}", fused.frame);
                assert!(fused.tracks.unwrap_or_default().is_empty());
                births = tracked.map_or(0, |(_, s)| s.births);
            }
            // The tracker heard of it (as `v2x-fuser track` gives it every fused box): a
            // track was confirmed, to be shown once its score reaches the operating point.
            assert_eq!(births, u64::from(track));
        }
        // At 0.9 the car is in the frame and its track is shown.
        let f = fusion(true);
        let (fused, _, _, _, state, _) = fuse_job(&f, f.fresh(), window(0, 0.9), 0);
        assert_eq!(fused.frame.detections.len(), 1);
        let (fused, ..) = fuse_job(&f, state, window(100_000, 0.9), 1);
        assert_eq!(fused.tracks.map(|t| t.len()), Some(1));
    }
}
