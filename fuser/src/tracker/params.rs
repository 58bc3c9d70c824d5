//! The tracker's parameters, grouped by what they govern: the tracks' motion, how boxes reach
//! them (the [`Association`] mode and its gate) and their management (births, confirmation,
//! output, deaths).

/// How each window's boxes reach the tracks (`docs/method.md` §8).
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Association {
    /// The fused boxes, each to the track of the best assignment ([`Tracker::step`](super::Tracker::step)).
    Assignment,
    /// The fused boxes, each track updated with its boxes weighed by the chance each is its
    /// own (`docs/method.md` §8.2).
    #[default]
    Soft,
    /// Each agent's boxes through the tracks first, fused between agents only where no track
    /// explains them ([`Tracker::step_agents`](super::Tracker::step_agents), `docs/method.md` §8.1).
    Guided,
    /// Simulation only: a box to the track of its ground-truth id (`Detection::id`, `NO_ID`
    /// never matching), ungated: what a perfect association gives with this filter.
    #[serde(skip)]
    ById,
}

impl Association {
    /// The modes a user may choose (by-id is the simulation's oracle).
    pub const CHOICES: [Association; 3] = [
        Association::Soft,
        Association::Assignment,
        Association::Guided,
    ];

    /// Its name on the command line, in scenarios and in Python.
    pub fn name(self) -> &'static str {
        match self {
            Association::Assignment => "assignment",
            Association::Soft => "soft",
            Association::Guided => "guided",
            Association::ById => "by-id",
        }
    }
}

impl std::fmt::Display for Association {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Association {
    type Err = v2x_protocol::UnknownName;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Association::CHOICES
            .into_iter()
            .find(|a| a.name() == s)
            .ok_or_else(|| {
                v2x_protocol::UnknownName::new(
                    "association",
                    s,
                    Association::CHOICES.iter().map(|a| a.name()),
                )
            })
    }
}

/// The tracks' motion models.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct TrackMotion {
    /// Std of the unmodelled acceleration (m/s^2) of the agile motion model, as in motion
    /// compensation.
    pub accel_std: f64,
    /// Std of the unmodelled acceleration (m/s^2) of the quiet motion model: an object keeping
    /// its course. Each track weighs the two models by how well each predicted its boxes
    /// (`docs/method.md` §8); equal to `accel_std`, one model.
    pub quiet_accel_std: f64,
    /// Mean time (s) an object keeps to one motion model before it may change to the other.
    pub mode_hold_s: f64,
    /// Std (m/s) of the velocity of a new track from a box without one.
    pub init_velocity_std: f64,
    /// Std (rad/s) of the yaw's change per second.
    pub yaw_rate_std: f64,
    /// Variance (m^2) the centre's height gains per second between boxes: 1, so that the
    /// height follows its boxes (a detector's heights scatter by tenths of a metre, and another
    /// car's pitch moves them more) instead of keeping the first box's.
    pub height_var_per_s: f64,
    /// Seconds of motion per second of window time: the replay speed when agents replay
    /// recorded data faster than real time on the wall clock (1 live).
    pub time_scale: f64,
}

impl Default for TrackMotion {
    fn default() -> Self {
        TrackMotion {
            accel_std: 2.0,
            quiet_accel_std: 0.5,
            mode_hold_s: 2.0,
            init_velocity_std: 10.0,
            yaw_rate_std: 0.5,
            height_var_per_s: 1.0,
            time_scale: 1.0,
        }
    }
}

/// How boxes are matched to tracks.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct AssociationParams {
    /// The mode.
    pub mode: Association,
    /// Gate on d^2 of a (track, box) pair: the 99.9% chi-square quantile for 4 degrees of
    /// freedom (centre and velocity measured); with the centre alone the same bound is looser.
    pub gate: f64,
    /// Soft association: the chance a tracked object yields a box in a window, in (0, 1).
    pub detect_prob: f64,
    /// Soft association: the density of boxes no track explains (new objects, false positives)
    /// per unit of the measurement's space (m^2 for a centre; m^2 (m/s)^2 with a velocity), > 0.
    pub new_density: f64,
}

impl Default for AssociationParams {
    fn default() -> Self {
        AssociationParams {
            mode: Association::default(),
            gate: 18.47,
            detect_prob: 0.9,
            new_density: 1e-5,
        }
    }
}

/// Which boxes become tracks, which tracks are shown and when they end.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Management {
    /// Hits in a row (the first box included) that confirm a track. 2: a box seen in one
    /// window only (a false positive, an object glimpsed once) never becomes a track.
    pub confirm_hits: u32,
    /// Misses in a row a confirmed track survives. 3: at 10 Hz a track coasts through 300 ms
    /// without boxes (an occlusion, lost windows); at 2 Hz, 1.5 s.
    pub max_misses: u32,
    /// Misses in a row during which a confirmed track is still output, at its prediction with
    /// its score halved per miss. 3, as `max_misses`: a window without a box (two tracks'
    /// boxes merged, a lost window) neither drops the object nor hands it to a neighbouring
    /// track, and the halved score lets the benchmark's thresholds drop long coasts.
    pub coast_output: u32,
    /// A confirmed track's box scoring below this is not output (the track goes on): the
    /// operating point of a detector's tracks ([`crate::uncertainty::detector::DetectorParams::min_score`]),
    /// 0 for boxes whose scores are not chances.
    pub min_score: f64,
    /// Longest gap between windows (s) tracks are carried over; beyond, they all end.
    pub max_gap_s: f64,
    /// Also follow the classes the nuScenes tracking benchmark does not score (barrier, traffic
    /// cone, construction vehicle); by default their boxes are passed over.
    pub all_classes: bool,
}

impl Default for Management {
    fn default() -> Self {
        Management {
            confirm_hits: 2,
            max_misses: 3,
            coast_output: 3,
            min_score: 0.0,
            max_gap_s: 2.0,
            all_classes: false,
        }
    }
}

/// Parameters of the tracker, by what they govern.
#[derive(Copy, Clone, Debug, Default, PartialEq)]
pub struct TrackerParams {
    /// The tracks' motion.
    pub motion: TrackMotion,
    /// How boxes reach tracks.
    pub association: AssociationParams,
    /// Births, confirmation, output and deaths.
    pub management: Management,
}

impl TrackerParams {
    /// The default parameters with boxes reaching tracks by `mode`.
    pub fn with_mode(mode: Association) -> Self {
        let mut p = TrackerParams::default();
        p.association.mode = mode;
        p
    }

    /// These parameters for tracking through the tracks (`guided`) or the fused boxes, a
    /// fused-box mode (soft or assignment) kept for the fused boxes.
    pub fn with_guided(self, guided: bool) -> Self {
        let mut p = self;
        p.association.mode = match (guided, self.association.mode) {
            (true, _) => Association::Guided,
            (false, Association::Guided) => Association::default(),
            (false, mode) => mode,
        };
        p
    }

    /// Whether each agent's boxes go through the tracks first ([`Association::Guided`]).
    pub fn guided(&self) -> bool {
        self.association.mode == Association::Guided
    }
}
