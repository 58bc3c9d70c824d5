//! One closed window through the steps every shell runs: the node's worker, offline fusion and
//! tracking (and through them the benches and the Python package). Sans-IO:
//!
//! 1. **models**: each agent's calibrated error model (`crate::uncertainty::stdmodel`);
//! 2. **learn**: the stds learned for each agent from its boxes so far (`crate::uncertainty::learn`);
//! 3. **motion**: every frame predicted to the window's reference time, its latest capture
//!    (`crate::time::motion`);
//! 4. **detector stds**: a detector's boxes given stds from their scores, the receiver's without
//!    the pose term (`crate::uncertainty::detector`), when the pipeline knows the receiver, unless step 1
//!    gave them their agent's calibrated stds;
//! 5. **registration**: every agent aligned to the reference agent (`crate::time::align`);
//! 6. **fusion**: the method, a CSBA-3D method scoring a detector's groups by noisy-OR with its
//!    tail dropped (`crate::uncertainty::detector::fuse_scored_sourced`).
//!
//! Steps 1-5 are [`Pipeline::prepare`] (a tracker through the tracks takes the lists from
//! there); step 6 is [`Steps::fuse`]. A new per-window step goes here, once, for every shell.

use crate::maths::fusion::Sourced;
use crate::time::align::{reference_agent, AlignParams, Aligner, Registration};
use crate::time::motion::{align_window, MotionParams};
use crate::time::window::Closed;
use crate::uncertainty::detector::{self, DetectorParams};
use crate::uncertainty::learn::{AgentReport, LearnParams, Learner};
use crate::uncertainty::stdmodel::Models;
use crate::Method;
use std::collections::BTreeMap;
use std::sync::Arc;
use v2x_protocol::{AgentKind, Detection};

/// What a window goes through: the method and the optional steps around it.
#[derive(Clone, Debug)]
pub struct Steps {
    /// The fusion method.
    pub method: Method,
    /// The boxes are a detector's ([`crate::uncertainty::detector`]): its group scores and tail, and with a
    /// receiver its stds.
    pub detector: Option<DetectorParams>,
    /// Motion compensation to the window's reference time (`None`: boxes as captured).
    pub motion: Option<MotionParams>,
    /// Registration to the reference agent.
    pub align: Option<AlignParams>,
    /// Stds learned online.
    pub learn: Option<LearnParams>,
    /// Calibrated error models, by agent name.
    pub models: Arc<Models>,
}

/// Sets the replay speed (seconds of motion per second of capture time) of every step that
/// predicts over time: motion compensation, the learner's tracker and a tracker. Settings are
/// built with 1 and scaled here, once.
pub fn set_time_scale(
    s: f64,
    motion: Option<&mut MotionParams>,
    learn: Option<&mut LearnParams>,
    track: Option<&mut crate::tracker::TrackerParams>,
) {
    if let Some(m) = motion {
        m.time_scale = s;
    }
    if let Some(l) = learn {
        l.tracker.motion.time_scale = s;
    }
    if let Some(t) = track {
        t.motion.time_scale = s;
    }
}

impl Steps {
    /// Just the method, no other step.
    pub fn method(method: Method) -> Steps {
        Steps {
            method,
            detector: None,
            motion: None,
            align: None,
            learn: None,
            models: Arc::new(Models::default()),
        }
    }

    /// Step 6: the agents' prepared boxes fused, each fused box with its agents; `receiver`:
    /// the position in `lists` of the agent whose frame the others' boxes arrive in.
    pub fn fuse(&self, lists: &[Vec<Detection>], receiver: Option<usize>) -> Vec<Sourced> {
        match (&self.detector, self.method.csba_params()) {
            (Some(p), Some(csba)) => detector::fuse_scored_sourced(p, &csba, lists, receiver),
            _ => self.method.fuse_sourced(lists),
        }
    }

    /// [`Steps::fuse`] without the agents of each box.
    pub fn fuse_boxes(&self, lists: &[Vec<Detection>], receiver: Option<usize>) -> Vec<Detection> {
        match (&self.detector, self.method.csba_params()) {
            (Some(p), Some(csba)) => detector::fuse_scored(p, &csba, lists, receiver),
            _ => self.method.fuse(lists),
        }
    }
}

/// The agent every other is registered to.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Reference {
    /// The first infrastructure agent of the window (surveyed, so its pose is the best known),
    /// else its first agent.
    Infrastructure,
    /// The agent of this name; a window without it is not registered.
    Agent(String),
}

/// A window after steps 1-5.
#[derive(Clone, Debug)]
pub struct Prepared {
    /// The reference time: the window's latest capture (us).
    pub t_ref: u64,
    /// The agents of the window, in name order.
    pub agents: Vec<String>,
    /// Each agent's boxes, ready to fuse (`agents` order).
    pub lists: Vec<Vec<Detection>>,
    /// Each agent's registration (`agents` order; `None`: not registered).
    pub registration: Vec<Option<Registration>>,
    /// The receiver's position in `agents`, if it is among them.
    pub receiver: Option<usize>,
}

/// The steps with what they carry from window to window (the learner's and the registration's
/// history).
#[derive(Clone, Debug)]
pub struct Pipeline {
    steps: Steps,
    reference: Reference,
    receiver: Option<String>,
    aligner: Option<Aligner>,
    learner: Option<Learner>,
}

impl Pipeline {
    /// A pipeline without history; `receiver`: the agent in whose frame the others' boxes
    /// arrive, for a detector's stds (`None`: the stds are the agents' own).
    pub fn new(steps: Steps, reference: Reference, receiver: Option<String>) -> Pipeline {
        Pipeline {
            aligner: steps.align.map(Aligner::new),
            learner: steps.learn.map(Learner::new),
            steps,
            reference,
            receiver,
        }
    }

    /// The steps.
    pub fn steps(&self) -> &Steps {
        &self.steps
    }

    /// What was learned of each agent's stds so far (empty without learning).
    pub fn learned(&self) -> BTreeMap<String, AgentReport> {
        self.learner
            .as_ref()
            .map(Learner::report)
            .unwrap_or_default()
    }

    /// Steps 1-5 for a closed window.
    pub fn prepare(&mut self, mut closed: Closed) -> Prepared {
        self.steps.models.apply_window(&mut closed);
        if let Some(l) = &mut self.learner {
            l.learn_window(&mut closed);
        }
        let agents: Vec<String> = closed.frames.keys().cloned().collect();
        let kinds: Vec<AgentKind> = closed.frames.values().map(|f| f.kind).collect();
        let (t_ref, lists) = align_window(closed, self.steps.motion.as_ref());
        let (lists, registration) = self.register(Some(t_ref), &agents, &kinds, lists);
        let receiver = self.receiver_in(&agents);
        Prepared {
            t_ref,
            agents,
            lists,
            registration,
            receiver,
        }
    }

    /// Steps 4-6 for one time step of every agent's boxes, each as captured at `t_us` (a
    /// bench's frame, a file's sample; `None`: boxes without a time): the fused boxes. The
    /// boxes are copied only when a step changes them.
    pub fn fuse_frame(
        &mut self,
        t_us: Option<u64>,
        agents: &[String],
        kinds: &[AgentKind],
        lists: &[Vec<Detection>],
    ) -> Vec<Detection> {
        let receiver = self.receiver_in(agents);
        let detector_stds = self.steps.detector.is_some() && self.receiver.is_some();
        if !detector_stds && self.aligner.is_none() {
            return self.steps.fuse_boxes(lists, receiver);
        }
        let (lists, _) = self.register(t_us, agents, kinds, lists.to_vec());
        self.steps.fuse_boxes(&lists, receiver)
    }

    /// The receiver's position among `agents`, if it is there.
    pub fn receiver_in(&self, agents: &[String]) -> Option<usize> {
        let r = self.receiver.as_ref()?;
        agents.iter().position(|a| a == r)
    }

    /// Steps 4-5 for the agents' boxes at time `t_us` (`None`: boxes without a time, each
    /// registered on its own evidence).
    pub fn register(
        &mut self,
        t_us: Option<u64>,
        agents: &[String],
        kinds: &[AgentKind],
        mut lists: Vec<Vec<Detection>>,
    ) -> (Vec<Vec<Detection>>, Vec<Option<Registration>>) {
        if let (Some(p), Some(receiver)) = (&self.steps.detector, &self.receiver) {
            // An agent with a calibrated model keeps the stds it gives.
            for (dets, name) in lists.iter_mut().zip(agents) {
                if !self.steps.models.0.contains_key(name) {
                    detector::ready(p, dets, name == receiver);
                }
            }
        }
        let Some(aligner) = &mut self.aligner else {
            return (lists, vec![None; agents.len()]);
        };
        let reference = match &self.reference {
            Reference::Infrastructure => Some(reference_agent(kinds)),
            Reference::Agent(name) => agents.iter().position(|a| a == name),
        };
        match reference {
            Some(r) => {
                let names: Vec<&str> = agents.iter().map(String::as_str).collect();
                aligner.align(t_us, &names, &lists, r)
            }
            None => (lists, vec![None; agents.len()]),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::uncertainty::stdmodel::{ErrorModel, ErrorSample};
    use v2x_protocol::{Class, Uncertainty};

    fn car(x: f64, score: f64) -> Detection {
        Detection {
            score,
            ..v2x_protocol::fixtures::car(x, 0.0, 0.5)
        }
    }

    #[test]
    fn the_replay_speed_reaches_every_step_that_predicts() {
        let (mut m, mut l, mut t) = (
            MotionParams::default(),
            LearnParams::default(),
            crate::tracker::TrackerParams::default(),
        );
        set_time_scale(4.0, Some(&mut m), Some(&mut l), Some(&mut t));
        assert_eq!(
            (
                m.time_scale,
                l.tracker.motion.time_scale,
                t.motion.time_scale
            ),
            (4.0, 4.0, 4.0)
        );
        let mut o = crate::offline::OfflineOptions::default();
        o.steps.learn = Some(LearnParams::default());
        o.set_time_scale(0.5);
        assert_eq!(o.steps.motion.unwrap().time_scale, 0.5);
        assert_eq!(o.steps.learn.unwrap().tracker.motion.time_scale, 0.5);
    }

    #[test]
    fn a_detectors_stds_come_from_the_score_unless_a_model_gives_them() {
        // Agent a00001's model: centre errors of exactly +-0.3 m on every axis.
        let samples: Vec<ErrorSample> = (0..40)
            .map(|i| ErrorSample {
                class: Class::Car,
                score: 0.5,
                error: {
                    let e = if i % 2 == 0 { 0.3 } else { -0.3 };
                    [e, e, e, 0.0, 0.0, 0.0, 0.0]
                },
                velocity: None,
            })
            .collect();
        let model = ErrorModel::fit(&samples, 1, "id").unwrap();
        let p = DetectorParams::default();
        let names = ["a00000".to_string(), "a00001".to_string()];
        let kinds = [AgentKind::Vehicle; 2];
        let lists = vec![vec![car(0.0, 0.9)], vec![car(0.2, 0.6)]];
        let pipeline = |models: Models| {
            let steps = Steps {
                detector: Some(p),
                models: Arc::new(models),
                ..Steps::method("csba-wls+".parse().unwrap())
            };
            Pipeline::new(
                steps,
                Reference::Agent(names[0].clone()),
                Some(names[0].clone()),
            )
        };
        // Without a model: the receiver's stds from its score, the other's with the pose too.
        let (ready, regs) =
            pipeline(Models::default()).register(None, &names, &kinds, lists.clone());
        assert_eq!(regs, vec![None, None]);
        assert_eq!(ready[0][0].std, detector::stds(&p, &lists[0][0], true));
        assert_eq!(ready[1][0].std, detector::stds(&p, &lists[1][0], false));
        // With a model for a00001, applied first (step 1), its stds stay as the model set them.
        let models = Models([(names[1].clone(), model)].into_iter().collect());
        let mut modelled = lists.clone();
        models.apply(&names[1], &mut modelled[1]);
        assert_ne!(modelled[1][0].std, Uncertainty::uniform(0.5, 0.1, 0.1));
        let (ready, _) = pipeline(models).register(None, &names, &kinds, modelled.clone());
        assert_eq!(ready[0][0].std, detector::stds(&p, &lists[0][0], true));
        assert_eq!(ready[1][0].std, modelled[1][0].std);
        // Fused as a detector's: one group, scored 1 - 0.1 x 0.4 = 0.96.
        let noisy_or = |models| {
            let mut p = pipeline(models);
            p.steps.detector = p.steps.detector.map(|d| DetectorParams {
                existence: None,
                ..d
            });
            p
        };
        let fused = noisy_or(Models::default()).steps().fuse(&ready, Some(0));
        assert_eq!(fused.len(), 1);
        assert!((fused[0].det.score - 0.96).abs() < 1e-12);
    }
}
