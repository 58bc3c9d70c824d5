//! The fusion worker: closed windows come in through a bounded queue, are fused on a blocking
//! thread (so a heavy window never stalls the receive loop), brought into the wire's domain,
//! encoded and published on `v2x/NS/fused`, in the order they closed; with tracking on, the
//! tracks the window updated follow on `v2x/NS/tracks`. Each outcome goes back to the receive
//! loop, which keeps the statistics.

use super::{Clock, Fused};
use crate::align::{reference_agent, AlignParams, Aligner};
use crate::detector::DetectorParams;
use crate::learn::{LearnParams, Learner};
use crate::motion::{align_window, MotionParams};
use crate::tracker::handover::{id_block, published, step_region, Handover};
use crate::tracker::{TrackStats, Tracker, TrackerParams};
use crate::window::Closed;
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
    pub closed_at_us: u64,
    pub done_at_us: u64,
}

/// Fuses one closed window into the frame the fuser publishes (not yet fitted to the wire),
/// stamped with the window's reference time: its latest capture. With `motion`, every frame is
/// first predicted to that time; with an `aligner`, every agent is then registered to the
/// roadside unit (`crate::align`). With a `learner`, the boxes are first given the stds learned
/// for their agent (`crate::learn`). With `detector`, a CSBA-3D method's groups are scored as a
/// detector's and its tail dropped (`crate::detector::fuse_scored`).
pub fn fuse_window(
    method: &Method,
    detector: Option<&DetectorParams>,
    motion: Option<&MotionParams>,
    aligner: Option<&mut Aligner>,
    learner: Option<&mut Learner>,
    mut closed: Closed,
    seq: u32,
) -> (Fused, Vec<Vec<Detection>>) {
    let learned = match learner {
        Some(l) => {
            l.learn_window(&mut closed);
            l.report()
        }
        None => Default::default(),
    };
    let agents: Vec<String> = closed.frames.keys().cloned().collect();
    let (t_ref, mut lists) = align_window(&closed, motion);
    let mut registration = std::collections::BTreeMap::new();
    if let Some(aligner) = aligner {
        let kinds: Vec<AgentKind> = closed.frames.values().map(|f| f.kind).collect();
        let names: Vec<&str> = agents.iter().map(String::as_str).collect();
        let (aligned, regs) = aligner.align(Some(t_ref), &names, &lists, reference_agent(&kinds));
        lists = aligned;
        for (name, r) in agents.iter().zip(regs) {
            registration.extend(r.map(|r| (name.clone(), r)));
        }
    }
    let sourced = match (detector, method.csba_params()) {
        (Some(p), Some(csba)) => crate::detector::fuse_scored_sourced(p, &csba, &lists),
        _ => method.fuse_sourced(&lists),
    };
    let (detections, sources) = sourced.into_iter().map(|s| (s.det, s.sources)).unzip();
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
            complete: closed.complete,
            sources,
        },
        tracks: None,
        registration,
        learned,
    };
    (fused, lists)
}

/// Keeps the fused boxes a region owns (centre in its tile), with their sources.
fn keep_owned(region: &crate::region::Region, fused: &mut Fused) {
    let dets = std::mem::take(&mut fused.frame.detections);
    let sources = std::mem::take(&mut fused.provenance.sources);
    let has_sources = sources.len() == dets.len();
    let mut sources = sources.into_iter();
    for d in dets {
        let s = if has_sources { sources.next() } else { None };
        if region.owns(&d) {
            fused.frame.detections.push(d);
            fused.provenance.sources.extend(s);
        }
    }
}

/// How the worker fuses: the method and the optional steps around it.
#[derive(Clone, Debug)]
pub(super) struct Fusion {
    pub method: Method,
    pub detector: Option<DetectorParams>,
    pub motion: Option<MotionParams>,
    pub align: Option<AlignParams>,
    pub track: Option<TrackerParams>,
    pub learn: Option<LearnParams>,
    pub models: std::sync::Arc<crate::stdmodel::Models>,
    pub region: Option<crate::region::Region>,
    /// A tracking regional fuser's neighbours' tracks, as heard.
    pub heard: Option<super::handover::Heard>,
}

/// What the worker carries from window to window.
struct Carried {
    aligner: Option<Aligner>,
    tracker: Option<Tracker>,
    handover: Option<Handover>,
    learner: Option<Learner>,
}

impl Fusion {
    fn fresh(&self) -> Carried {
        // A region's tracks take ids of its tile's own block, so no two regions give one id.
        let tracker = self.track.map(|p| match &self.region {
            Some(r) => Tracker::with_ids(p, id_block(r.tile)),
            None => Tracker::new(p),
        });
        Carried {
            aligner: self.align.map(Aligner::new),
            tracker,
            handover: self.track.and(self.region).map(Handover::new),
            learner: self.learn.map(Learner::new),
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
    region: Option<&crate::region::Region>,
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
);

/// Fuses one closed window on a blocking thread: the calibrated models, the learned stds,
/// fusion, the region's share, the wire's domain, then the tracks (fed, in a region, every
/// fused box of its tile and halo in the wire's domain, after its neighbours' ids).
fn fuse_job(f: &Fusion, mut state: Carried, mut closed: Closed, seq: u32) -> JobOutput {
    f.models.apply_window(&mut closed);
    let (mut fused, lists) = fuse_window(
        &f.method,
        f.detector.as_ref(),
        f.motion.as_ref(),
        state.aligner.as_mut(),
        state.learner.as_mut(),
        closed,
        seq,
    );
    let mut halo = None;
    if let Some(r) = &f.region {
        if state.tracker.is_some() {
            let mut all = fused.frame.clone();
            wire::fit(&mut all);
            halo = Some(all);
        }
        keep_owned(r, &mut fused);
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
        let input = halo.as_ref().unwrap_or(&fused.frame);
        let frame = tracks_frame(t, input, &lists, &f.method, f.region.as_ref());
        let bytes = wire::encode(&frame);
        fused.tracks = Some(frame.detections);
        (bytes, t.stats())
    });
    (fused, fit, bytes, tracked, state)
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
                aligner: None,
                tracker: None,
                handover: None,
                learner: None,
            },
        );
        let f = fusion.clone();
        let work = tokio::task::spawn_blocking(move || fuse_job(&f, state, closed, this_seq)).await;
        // A fusion that panicked took the aligner and the tracks with it: start afresh.
        let (work, tracked) = match work {
            Ok((fused, fit, bytes, tracked, state)) => {
                carried = state;
                (Ok((fused, fit, bytes)), tracked)
            }
            Err(e) => {
                carried = fusion.fresh();
                (Err(e), None)
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
            closed_at_us,
            done_at_us: clock.now_us(),
        };
        if done.send(outcome).is_err() {
            break;
        }
    }
}
