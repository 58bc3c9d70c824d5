//! Time alignment of agents' frames, sans-IO: no clock, no network. The caller passes "now" on
//! the fuser's clock, in the same time base as capture times (microseconds since the Unix epoch),
//! and the set of agents a window waits for.
//!
//! A window is anchored at the capture time of the first frame that opens it and takes the frames
//! whose capture time lies within delta t / 2 of the anchor, one per agent: of two frames of one
//! agent, the one closer to the anchor stays and the other is counted as replaced. A window closes
//! when every awaited agent has contributed, or when its deadline passes: max(first arrival,
//! anchor) + max wait. Taking the later of the two means a frame stamped ahead of the fuser's
//! clock holds only its own window until its time comes, and cannot close the windows of everyone
//! else early. Closing a window first closes every older one, so windows come out in capture
//! order. A frame for a closed window is late (but an agent's next frame after one it had in the
//! last closed window opens a new window, even within that window's reach, so that windows wider
//! than an agent's frame period lose nothing); a frame already seen (same agent, sequence number
//! and capture time) is a duplicate. Both are counted and dropped by the caller, never fused twice.

use std::collections::{BTreeMap, BTreeSet, HashMap, VecDeque};
use v2x_protocol::Frame;

/// What happened to an inserted frame.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Verdict {
    /// Joined an open window.
    Accepted,
    /// Joined an open window in place of the same agent's frame that lay farther from the
    /// anchor (that one is dropped).
    Replaced,
    /// Dropped: the same agent's frame already in that window lies closer to the anchor.
    Superseded,
    /// Its window was already closed.
    Late,
    /// Already seen (same agent, sequence number and capture time).
    Duplicate,
}

/// A window ready to fuse.
#[derive(Clone, Debug, PartialEq)]
pub struct Closed {
    /// Capture time of the frame that opened it (us).
    pub anchor_us: u64,
    /// One frame per agent, by agent name.
    pub frames: BTreeMap<String, Frame>,
    /// Whether every awaited agent contributed.
    pub complete: bool,
    /// When its first frame arrived (fuser clock, us).
    pub first_arrival_us: u64,
}

impl Closed {
    /// A complete window of these frames (one per agent), anchored at their earliest capture
    /// and arrived then: frames already grouped, as a bench's or a test's.
    pub fn of(frames: impl IntoIterator<Item = Frame>) -> Closed {
        let frames: BTreeMap<String, Frame> =
            frames.into_iter().map(|f| (f.agent.clone(), f)).collect();
        let anchor_us = frames.values().map(|f| f.capture_us).min().unwrap_or(0);
        Closed {
            anchor_us,
            frames,
            complete: true,
            first_arrival_us: anchor_us,
        }
    }
}

#[derive(Debug)]
struct Open {
    anchor_us: u64,
    first_arrival_us: u64,
    frames: BTreeMap<String, Frame>,
}

/// The window state machine.
#[derive(Debug)]
pub struct Windows {
    delta_us: u64,
    max_wait_us: u64,
    open: Vec<Open>,
    last_closed: Option<u64>,
    /// The agents of the last closed window.
    last_members: BTreeSet<String>,
    /// Per agent, the latest capture time of its frames in closed windows.
    fused_until: HashMap<String, u64>,
    recent: HashMap<String, VecDeque<(u32, u64)>>,
}

/// How many (sequence, capture time) pairs per agent are remembered to spot duplicates.
const RECENT: usize = 64;

impl Windows {
    /// Windows of `delta_us` that wait at most `max_wait_us` after their first frame.
    pub fn new(delta_us: u64, max_wait_us: u64) -> Self {
        Windows {
            delta_us: delta_us.max(2),
            max_wait_us,
            open: Vec::new(),
            last_closed: None,
            last_members: BTreeSet::new(),
            fused_until: HashMap::new(),
            recent: HashMap::new(),
        }
    }

    /// Forgets an agent's recent sequence numbers (it restarted and counts from 0 again).
    pub fn reset_agent(&mut self, agent: &str) {
        self.recent.remove(agent);
    }

    /// Forgets an agent entirely (it is no longer tracked): its recent sequence numbers and its
    /// frames in open windows, so that memory stays bounded by the agents tracked.
    pub fn forget_agent(&mut self, agent: &str) {
        self.recent.remove(agent);
        self.last_members.remove(agent);
        self.fused_until.remove(agent);
        for w in &mut self.open {
            w.frames.remove(agent);
        }
        self.open.retain(|w| !w.frames.is_empty());
    }

    /// Number of agents whose recent frames are remembered.
    pub fn remembered_agents(&self) -> usize {
        self.recent.len()
    }

    /// Number of open windows.
    pub fn open_windows(&self) -> usize {
        self.open.len()
    }

    /// Number of frames held in open windows.
    pub fn open_frames(&self) -> usize {
        self.open.iter().map(|w| w.frames.len()).sum()
    }

    fn deadline(&self, w: &Open) -> u64 {
        w.first_arrival_us
            .max(w.anchor_us)
            .saturating_add(self.max_wait_us)
    }

    /// Offers a frame that arrived at `now_us`.
    pub fn insert(&mut self, frame: Frame, now_us: u64) -> Verdict {
        let key = (frame.seq, frame.capture_us);
        let recent = self.recent.entry(frame.agent.clone()).or_default();
        // Also held in an open window: possible when the agent's recent keys were reset (it
        // rejoined) and it sends the same frame again.
        let held = |w: &Open| {
            w.frames
                .get(&frame.agent)
                .is_some_and(|f| (f.seq, f.capture_us) == key)
        };
        if recent.contains(&key) || self.open.iter().any(held) {
            return Verdict::Duplicate;
        }
        recent.push_back(key);
        if recent.len() > RECENT {
            recent.pop_front();
        }
        let half = self.delta_us / 2;
        let t = frame.capture_us;
        if let Some(c) = self.last_closed {
            // Within the last closed window's reach, a frame is late unless its agent was in
            // that window and the frame is newer than every frame of the agent fused so far:
            // then it is that agent's next frame, and it opens (or joins) a window after the
            // closed one.
            let next = t > c
                && self.last_members.contains(&frame.agent)
                && self.fused_until.get(&frame.agent).is_some_and(|&f| t > f);
            if t < c.saturating_add(half) && !next {
                return Verdict::Late;
            }
        }
        let nearest = self
            .open
            .iter_mut()
            .filter(|w| w.anchor_us.abs_diff(t) < half)
            .min_by_key(|w| w.anchor_us.abs_diff(t));
        match nearest {
            Some(w) => {
                let anchor = w.anchor_us;
                match w.frames.get_mut(&frame.agent) {
                    Some(held) if held.capture_us.abs_diff(anchor) <= t.abs_diff(anchor) => {
                        Verdict::Superseded
                    }
                    Some(held) => {
                        *held = frame;
                        Verdict::Replaced
                    }
                    None => {
                        w.frames.insert(frame.agent.clone(), frame);
                        Verdict::Accepted
                    }
                }
            }
            None => {
                let pos = self.open.partition_point(|w| w.anchor_us <= t);
                let mut frames = BTreeMap::new();
                frames.insert(frame.agent.clone(), frame);
                self.open.insert(
                    pos,
                    Open {
                        anchor_us: t,
                        first_arrival_us: now_us,
                        frames,
                    },
                );
                Verdict::Accepted
            }
        }
    }

    /// When the next deadline falls (fuser clock, us), if any window is open.
    pub fn next_deadline(&self) -> Option<u64> {
        self.open.iter().map(|w| self.deadline(w)).min()
    }

    /// Half the window width (us): frames within it of an anchor join that window.
    pub fn half_us(&self) -> u64 {
        self.delta_us / 2
    }

    /// Closes what is ready: the newest window that is complete (every agent `awaited(anchor)`
    /// names is in it) or past its deadline, and every window older than it.
    pub fn poll(&mut self, now_us: u64, awaited: impl Fn(u64) -> BTreeSet<String>) -> Vec<Closed> {
        let complete = |w: &Open| {
            let want = awaited(w.anchor_us);
            !want.is_empty() && want.iter().all(|a| w.frames.contains_key(a))
        };
        let ready = self
            .open
            .iter()
            .rposition(|w| complete(w) || now_us >= self.deadline(w));
        let Some(last) = ready else {
            return Vec::new();
        };
        let closed: Vec<Closed> = self
            .open
            .drain(..=last)
            .map(|w| Closed {
                complete: complete(&w),
                anchor_us: w.anchor_us,
                frames: w.frames,
                first_arrival_us: w.first_arrival_us,
            })
            .collect();
        for w in &closed {
            for (a, f) in &w.frames {
                let until = self.fused_until.entry(a.clone()).or_insert(f.capture_us);
                *until = (*until).max(f.capture_us);
            }
        }
        if let Some(c) = closed.last() {
            self.last_closed = Some(c.anchor_us);
            self.last_members = c.frames.keys().cloned().collect();
        }
        closed
    }

    /// Closes every open window (at shutdown).
    pub fn flush(&mut self, awaited: impl Fn(u64) -> BTreeSet<String>) -> Vec<Closed> {
        self.poll(u64::MAX, awaited)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use v2x_protocol::AgentKind;

    fn f(agent: &str, seq: u32, t_ms: u64) -> Frame {
        Frame {
            agent: agent.into(),
            kind: AgentKind::Vehicle,
            seq,
            capture_us: t_ms * 1000,
            origin: [0.0; 3],
            detections: vec![],
        }
    }

    fn live(names: &[&str]) -> BTreeSet<String> {
        names.iter().map(|s| s.to_string()).collect()
    }

    const MS: u64 = 1000;

    #[test]
    fn closes_when_every_live_agent_contributed() {
        let mut w = Windows::new(100 * MS, 150 * MS);
        let l = live(&["a", "b"]);
        assert_eq!(w.insert(f("a", 0, 1000), 1000 * MS), Verdict::Accepted);
        assert!(w.poll(1000 * MS + 1, |_| l.clone()).is_empty());
        // b's clock is 20 ms off: same window
        assert_eq!(w.insert(f("b", 0, 1020), 1005 * MS), Verdict::Accepted);
        let c = w.poll(1005 * MS, |_| l.clone());
        assert_eq!(c.len(), 1);
        assert!(c[0].complete);
        assert_eq!(c[0].anchor_us, 1000 * MS);
        assert_eq!(c[0].frames.len(), 2);
    }

    #[test]
    fn a_window_wider_than_the_period_loses_no_frame() {
        // 150 ms windows, agents at 10 Hz 50 ms apart; b's frame arrives first and anchors.
        let mut w = Windows::new(150 * MS, 150 * MS);
        let l = live(&["a", "b"]);
        assert_eq!(w.insert(f("b", 0, 1050), 1051 * MS), Verdict::Accepted);
        assert_eq!(w.insert(f("a", 0, 1000), 1052 * MS), Verdict::Accepted);
        let c = w.poll(1052 * MS, |_| l.clone());
        assert_eq!((c.len(), c[0].anchor_us), (1, 1050 * MS));
        // a's next frame is 50 ms from the closed anchor: a new window, not late
        assert_eq!(w.insert(f("a", 1, 1100), 1101 * MS), Verdict::Accepted);
        assert_eq!(w.insert(f("b", 1, 1150), 1151 * MS), Verdict::Accepted);
        let c = w.poll(1151 * MS, |_| l.clone());
        assert_eq!(c[0].anchor_us, 1100 * MS);
        assert_eq!(c[0].frames.len(), 2);
        // an agent that was not in the closed window is late within its reach
        assert_eq!(w.insert(f("c", 0, 1120), 1152 * MS), Verdict::Late);
        // and so is an agent's frame no newer than the closed anchor
        assert_eq!(w.insert(f("a", 7, 1099), 1152 * MS), Verdict::Late);
    }

    #[test]
    fn deadline_closes_an_incomplete_window() {
        let mut w = Windows::new(100 * MS, 150 * MS);
        let l = live(&["a", "b"]);
        // arrives 30 ms after capture: the deadline counts from the arrival
        w.insert(f("a", 0, 1000), 1030 * MS);
        assert_eq!(w.next_deadline(), Some(1180 * MS));
        assert!(w.poll(1179 * MS, |_| l.clone()).is_empty());
        let c = w.poll(1180 * MS, |_| l.clone());
        assert_eq!(c.len(), 1);
        assert!(!c[0].complete);
        // b's frame comes after the window closed: late, never fused
        assert_eq!(w.insert(f("b", 0, 1010), 1190 * MS), Verdict::Late);
        assert!(w.flush(|_| l.clone()).is_empty());
    }

    #[test]
    fn a_frame_stamped_ahead_holds_only_its_own_window() {
        let mut w = Windows::new(100 * MS, 150 * MS);
        let l = live(&["a", "b"]);
        // a's clock is 900 ms ahead: its frame arrives now (t = 1000 ms) stamped 1900 ms.
        assert_eq!(w.insert(f("a", 0, 1900), 1000 * MS), Verdict::Accepted);
        assert_eq!(w.next_deadline(), Some(2050 * MS), "not 1150 ms");
        assert!(w.poll(1200 * MS, |_| l.clone()).is_empty());
        // honest frames keep flowing and fuse in their own windows
        w.insert(f("b", 0, 1300), 1301 * MS);
        let c = w.poll(1460 * MS, |_| l.clone());
        assert_eq!(
            c.iter().map(|c| c.anchor_us).collect::<Vec<_>>(),
            vec![1300 * MS]
        );
        assert_eq!(w.insert(f("b", 1, 1400), 1461 * MS), Verdict::Accepted);
        assert_eq!(w.open_windows(), 2);
    }

    #[test]
    fn duplicates() {
        let mut w = Windows::new(100 * MS, 150 * MS);
        assert_eq!(w.insert(f("a", 0, 1000), 0), Verdict::Accepted);
        assert_eq!(w.insert(f("a", 0, 1000), 1), Verdict::Duplicate);
        // after a restart the agent counts from 0 again at a new capture time: fine
        assert_eq!(w.insert(f("a", 0, 1100), 3), Verdict::Accepted);
    }

    #[test]
    fn of_two_frames_of_one_agent_the_closer_to_the_anchor_stays() {
        let mut w = Windows::new(100 * MS, 150 * MS);
        let l = live(&["fast", "slow"]);
        // A 20 Hz agent with jitter puts two frames in one window anchored by the 10 Hz one.
        assert_eq!(w.insert(f("slow", 0, 1000), 0), Verdict::Accepted);
        assert_eq!(w.insert(f("fast", 0, 1040), 0), Verdict::Accepted);
        assert_eq!(w.insert(f("fast", 1, 1010), 0), Verdict::Replaced);
        assert_eq!(w.insert(f("fast", 2, 960), 0), Verdict::Superseded);
        let c = w.poll(0, |_| l.clone());
        assert_eq!(c.len(), 1);
        assert_eq!(
            c[0].frames["fast"].seq, 1,
            "the frame 10 ms from the anchor"
        );
    }

    #[test]
    fn out_of_order_frames_join_their_window_and_windows_close_in_order() {
        let mut w = Windows::new(100 * MS, 150 * MS);
        let l = live(&["a", "b"]);
        w.insert(f("a", 1, 1100), 0);
        w.insert(f("a", 0, 1000), 1); // arrives after a newer one
        w.insert(f("b", 0, 1000), 2);
        let c = w.poll(3, |_| l.clone());
        assert_eq!(c.len(), 1, "the older window is complete; the newer waits");
        assert_eq!(c[0].anchor_us, 1000 * MS);
        w.insert(f("b", 1, 1101), 4);
        // completing the newest closes it (and anything older)
        let c = w.poll(5, |_| l.clone());
        assert_eq!(
            c.iter().map(|c| c.anchor_us).collect::<Vec<_>>(),
            vec![1100 * MS]
        );
    }

    #[test]
    fn a_complete_newer_window_closes_older_incomplete_ones_first() {
        let mut w = Windows::new(100 * MS, 1000 * MS);
        let l = live(&["a", "b"]);
        w.insert(f("a", 0, 1000), 0); // b's frame for 1000 was lost
        w.insert(f("a", 1, 1100), 1);
        w.insert(f("b", 1, 1100), 2);
        let c = w.poll(3, |_| l.clone());
        assert_eq!(c.len(), 2);
        assert_eq!((c[0].anchor_us, c[0].complete), (1000 * MS, false));
        assert_eq!((c[1].anchor_us, c[1].complete), (1100 * MS, true));
        assert_eq!(w.insert(f("b", 0, 1000), 4), Verdict::Late);
    }

    #[test]
    fn with_no_awaited_agent_only_deadlines_close() {
        let mut w = Windows::new(100 * MS, 50 * MS);
        w.insert(f("a", 0, 0), 0);
        assert!(w.poll(10, |_| BTreeSet::new()).is_empty());
        assert_eq!(w.poll(50 * MS, |_| BTreeSet::new()).len(), 1);
    }

    #[test]
    fn forgetting_an_agent_frees_its_memory() {
        let mut w = Windows::new(100 * MS, 50 * MS);
        for i in 0..100 {
            w.insert(f(&format!("a{i}"), 0, 0), 0);
        }
        assert_eq!(w.remembered_agents(), 100);
        assert_eq!(w.open_frames(), 100);
        for i in 0..100 {
            w.forget_agent(&format!("a{i}"));
        }
        assert_eq!(w.remembered_agents(), 0);
        assert_eq!((w.open_frames(), w.open_windows()), (0, 0));
    }
}
