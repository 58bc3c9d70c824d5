//! A scene as the nuScenes devkit scores it: tracks at their mean score, interpolated over
//! their gaps, and the fragmentations of an object's tracked frames.

use super::*;

/// A scene as the devkit scores it: each track's boxes at the track's mean score, and every
/// track (ground truth or predicted) filled in between its first and last frame.
pub(super) fn prepare(scene: &Scene) -> Scene {
    let mut out = scene.clone();
    let mut sums: HashMap<usize, (f64, usize)> = HashMap::new();
    for h in scene.frames.iter().flat_map(|f| &f.hyps) {
        let e = sums.entry(h.track).or_default();
        e.0 += h.score;
        e.1 += 1;
    }
    for h in out.frames.iter_mut().flat_map(|f| &mut f.hyps) {
        let (sum, n) = sums[&h.track];
        h.score = sum / n as f64;
    }
    let times: Vec<u64> = scene.frames.iter().map(|f| f.t_us).collect();
    let seen = by_first_appearance(out.frames.iter().map(|f| f.gt.iter().map(|o| (o.id, o))));
    for (k, xy, right) in gaps(&seen, &times) {
        out.frames[k].gt.push(Obj { xy, ..right });
    }
    let seen = by_first_appearance(
        out.frames
            .iter()
            .map(|f| f.hyps.iter().map(|h| (h.track, h))),
    );
    for (k, xy, right) in gaps(&seen, &times) {
        out.frames[k].hyps.push(Hyp { xy, ..right });
    }
    out
}

/// Each track's boxes with their frame index, the tracks in the order the devkit's
/// `interpolate_tracks` meets them (frame by frame, each frame's list in order), so that the
/// boxes it fills in follow each frame's own boxes in that order.
fn by_first_appearance<'a, K, B, F, I>(frames: F) -> Vec<Vec<(usize, B)>>
where
    K: std::hash::Hash + Eq,
    B: Clone + 'a,
    F: Iterator<Item = I>,
    I: Iterator<Item = (K, &'a B)>,
{
    let mut index: HashMap<K, usize> = HashMap::new();
    let mut tracks: Vec<Vec<(usize, B)>> = Vec::new();
    for (k, boxes) in frames.enumerate() {
        for (key, b) in boxes {
            let n = tracks.len();
            let t = *index.entry(key).or_insert(n);
            if t == n {
                tracks.push(Vec::new());
            }
            tracks[t].push((k, b.clone()));
        }
    }
    tracks
}

/// A box the metrics can interpolate.
trait Located: Clone {
    fn xy(&self) -> [f64; 2];
}

impl Located for Obj {
    fn xy(&self) -> [f64; 2] {
        self.xy
    }
}

impl Located for Hyp {
    fn xy(&self) -> [f64; 2] {
        self.xy
    }
}

/// The devkit's `interpolate_tracks`: for each frame between a track's first and last that
/// lacks it, the centre from its neighbours (weights as the devkit sets them) and the right
/// neighbour's other fields.
fn gaps<B: Located>(seen: &[Vec<(usize, B)>], times: &[u64]) -> Vec<(usize, [f64; 2], B)> {
    let mut out = Vec::new();
    for boxes in seen {
        for pair in boxes.windows(2) {
            let ((l, left), (r, right)) = (&pair[0], &pair[1]);
            for k in l + 1..*r {
                let w = (times[*r] - times[k]) as f64 / (times[*r] - times[*l]) as f64;
                let (a, b) = (left.xy(), right.xy());
                let xy = [(1.0 - w) * a[0] + w * b[0], (1.0 - w) * a[1] + w * b[1]];
                out.push((k, xy, right.clone()));
            }
        }
    }
    out
}

/// Times an object goes from tracked to untracked between its first and last tracked frame.
pub(super) fn fragmentations(tracked: &[bool]) -> usize {
    let (Some(first), Some(last)) = (
        tracked.iter().position(|t| *t),
        tracked.iter().rposition(|t| *t),
    ) else {
        return 0;
    };
    tracked[first..=last]
        .windows(2)
        .filter(|w| w[0] && !w[1])
        .count()
}
