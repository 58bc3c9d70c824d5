//! The `Fuser` API: one list of detections per agent for a time step in, fused detections out.
//! A [`Method`] is a value, so CSBA-WLS, its variants, the baselines and the oracle are used the
//! same way, by name, from the library, the `v2x-fuser fuse` command and the fuser node.

use crate::maths::association::{associate, mahalanobis, CsbaParams, CHI2_2_999, CHI2_3_999};
use crate::maths::baselines;
use crate::maths::fusion::GroupSum;
use crate::maths::parts::in_parts;
use std::borrow::Borrow;
use std::fmt;
use std::str::FromStr;
use v2x_protocol::{AgentSet, Detection, UnknownName};

pub use crate::maths::fusion::Sourced;

impl Sourced {
    /// Pairs boxes with their source sets, in order.
    pub fn zip(dets: Vec<Detection>, sources: Vec<AgentSet>) -> Vec<Sourced> {
        dets.into_iter()
            .zip(sources)
            .map(|(det, sources)| Sourced { det, sources })
            .collect()
    }
}

/// A late-fusion method.
#[derive(Copy, Clone, Debug, PartialEq)]
pub enum Method {
    /// CSBA-3D association (sequential pairwise over agents) then WLS-3D fusion.
    Csba(CsbaParams),
    /// Greedy NMS on rotated 3D IoU.
    Nms3d,
    /// Greedy NMS on 3D GIoU.
    NmsGiou3d,
    /// Weighted boxes fusion on rotated 3D IoU.
    Wbf3d,
    /// PSA: argmax of IoU-weighted score in one-hop clusters.
    Psa,
    /// InfraDet3D late fusion.
    InfraDet3dLate,
    /// DAIR-V2X late fusion.
    DairV2xLate,
    /// Oracle: ground-truth association, WLS-3D fusion.
    GtWls,
}

/// A method as it is registered: its name (as the CLI spells it), a line on what it is (as
/// `--help` lists it), and the method.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Named {
    /// The name.
    pub name: &'static str,
    /// What it is, in one line.
    pub about: &'static str,
    /// The method.
    pub method: Method,
    /// An ablation: a row of `v2x-sim bench` (`--methods NAME`), not a choice of the fuser's
    /// commands, scenarios or Python, since it wins nowhere.
    pub ablation: bool,
}

const fn named(name: &'static str, about: &'static str, method: Method) -> Named {
    Named {
        name,
        about,
        method,
        ablation: false,
    }
}

/// A bench-only ablation.
const fn ablation(name: &'static str, about: &'static str, method: Method) -> Named {
    Named {
        name,
        about,
        method,
        ablation: true,
    }
}

const PAPER: CsbaParams = CsbaParams::PAPER;
const PLUS: CsbaParams = CsbaParams::PLUS;

/// The method every command, scenario and bench uses unless told otherwise: csba-wls+.
pub const DEFAULT: Method = Method::Csba(PLUS);

impl Default for Method {
    fn default() -> Self {
        DEFAULT
    }
}

/// Every method, registered once: names, parsing, `--help` and [`Method::all`] come from here
/// (the ablations only for `v2x-sim bench`, [`Method::parse_any`]).
pub const METHODS: &[Named] = &[
    named(
        "csba-wls",
        "CSBA-3D association + WLS-3D fusion, exactly as the paper prints it",
        Method::Csba(PAPER),
    ),
    named(
        "csba-wls+",
        "csba-wls with a scale-consistent Mahalanobis gate and the wrapped orientation score",
        Method::Csba(PLUS),
    ),
    named(
        "csba-wls+chi2",
        "csba-wls+ where a member beyond the 99.9% chi-square bound of its group starts its own",
        Method::Csba(CsbaParams {
            consistency: Some(CHI2_3_999),
            ..PLUS
        }),
    ),
    named(
        "csba-wls+vel",
        "csba-wls+ where a pair whose velocities differ beyond their 99.9% chi-square bound is not eligible",
        Method::Csba(CsbaParams {
            velocity_gate: Some(CHI2_2_999),
            ..PLUS
        }),
    ),
    ablation(
        "csba-wls+gate",
        "ablation: csba-wls with only the Mahalanobis gate of csba-wls+",
        Method::Csba(CsbaParams {
            gate: PLUS.gate,
            ..PAPER
        }),
    ),
    ablation(
        "csba-wls+orient",
        "ablation: csba-wls with only the wrapped orientation score of csba-wls+",
        Method::Csba(CsbaParams {
            orientation: PLUS.orientation,
            ..PAPER
        }),
    ),
    ablation(
        "csba-wls+dim",
        "ablation: csba-wls with only the symmetric dimension score of csba-wls+",
        Method::Csba(CsbaParams {
            dimension: PLUS.dimension,
            ..PAPER
        }),
    ),
    ablation(
        "csba-wls+loglik",
        "ablation: csba-wls with only the Gaussian centre score and log-likelihood cost",
        Method::Csba(CsbaParams {
            centre: PLUS.centre,
            combine: PLUS.combine,
            ..PAPER
        }),
    ),
    named(
        "nms-3d",
        "greedy NMS over all agents, rotated 3D IoU > 0.15 suppresses, keeps the top box",
        Method::Nms3d,
    ),
    named(
        "nms-giou-3d",
        "greedy NMS over all agents, 3D GIoU > 0.15 suppresses, keeps the top box",
        Method::NmsGiou3d,
    ),
    named(
        "wbf-3d",
        "weighted boxes fusion, clusters by 3D IoU > 0.55, score-weighted mean box",
        Method::Wbf3d,
    ),
    named(
        "psa",
        "one-hop BEV-IoU clusters within 10 m, keeps the argmax of IoU-weighted score",
        Method::Psa,
    ),
    named(
        "infradet3d-late",
        "Hungarian on 2D centre distance (3 m gate), mean box, first agent's yaw",
        Method::InfraDet3dLate,
    ),
    named(
        "dair-v2x-late",
        "Hungarian on 3D centre distance within a class (3 m gate), mean of the pair",
        Method::DairV2xLate,
    ),
    named(
        "gt-wls",
        "oracle: groups by ground-truth id (instance_token), WLS-3D fusion",
        Method::GtWls,
    ),
];

impl Method {
    /// The method's name as the CLI spells it (`csba-wls(custom)` for CSBA-3D parameters no
    /// name is registered for).
    pub fn name(&self) -> String {
        METHODS
            .iter()
            .find(|n| n.method == *self)
            .map_or_else(|| "csba-wls(custom)".to_string(), |n| n.name.to_string())
    }

    /// The association's parameters, for a CSBA-3D method.
    pub fn csba_params(&self) -> Option<CsbaParams> {
        match self {
            Method::Csba(p) => Some(*p),
            _ => None,
        }
    }

    /// Every method a user may choose, in the order of [`METHODS`].
    pub fn all() -> Vec<Method> {
        METHODS
            .iter()
            .filter(|n| !n.ablation)
            .map(|n| n.method)
            .collect()
    }

    /// Every registered method, the ablations too (`v2x-sim bench --methods all`).
    pub fn all_with_ablations() -> Vec<Method> {
        METHODS.iter().map(|n| n.method).collect()
    }

    /// A method by name, an ablation too (`v2x-sim bench --methods`).
    pub fn parse_any(s: &str) -> Result<Method, UnknownName> {
        METHODS
            .iter()
            .find(|n| n.name == s)
            .map(|n| n.method)
            .ok_or_else(|| UnknownName::new("method", s, METHODS.iter().map(|n| n.name)))
    }

    /// Fuses one time step: `agents[k]` is agent k's detections, agents in a fixed order.
    pub fn fuse(&self, agents: &[Vec<Detection>]) -> Vec<Detection> {
        if let Method::Csba(p) = self {
            return csba_wls_parts(p, agents).0;
        }
        self.fuse_sourced(agents)
            .into_iter()
            .map(|s| s.det)
            .collect()
    }

    /// Fuses one time step like [`Method::fuse`], saying for each box which agents went into it.
    pub fn fuse_sourced(&self, agents: &[Vec<Detection>]) -> Vec<Sourced> {
        match self {
            Method::Csba(p) => csba_wls(p, agents),
            Method::Nms3d => baselines::nms_3d(agents),
            Method::NmsGiou3d => baselines::nms_giou_3d(agents),
            Method::Wbf3d => baselines::wbf_3d(agents),
            Method::Psa => baselines::psa(agents),
            Method::InfraDet3dLate => baselines::infradet3d_late(agents),
            Method::DairV2xLate => baselines::dair_v2x_late(agents),
            Method::GtWls => baselines::gt_wls(agents),
        }
    }
}

impl fmt::Display for Method {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.name())
    }
}

/// The command line's `--method`: the methods a user may choose, each listed in `--help` with
/// its line from [`METHODS`].
#[cfg(feature = "node")]
pub fn method_parser() -> impl clap::builder::TypedValueParser<Value = Method> {
    use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
    let names = METHODS
        .iter()
        .filter(|n| !n.ablation)
        .map(|n| PossibleValue::new(n.name).help(n.about));
    PossibleValuesParser::new(names).map(|s| s.parse().expect("a listed name parses"))
}

/// A method a user may choose, by name (an ablation is the bench's: [`Method::parse_any`]).
impl FromStr for Method {
    type Err = UnknownName;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let users = || METHODS.iter().filter(|n| !n.ablation);
        users()
            .find(|n| n.name == s)
            .map(|n| n.method)
            .ok_or_else(|| UnknownName::new("method", s, users().map(|n| n.name)))
    }
}

impl serde::Serialize for Method {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(&self.name())
    }
}

impl<'de> serde::Deserialize<'de> for Method {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let name = String::deserialize(d)?;
        name.parse().map_err(serde::de::Error::custom)
    }
}

/// CSBA-WLS over N agents: the running fused set (with its WLS covariances) is associated with
/// each next agent's list in agent order (`docs/method.md` §1); each group is fused from all its
/// members, a joining member's terms added to the group's sums.
pub fn csba_wls(p: &CsbaParams, agents: &[Vec<Detection>]) -> Vec<Sourced> {
    let (fused, sources) = csba_wls_parts(p, agents);
    Sourced::zip(fused, sources)
}

/// [`csba_wls`] as the fused boxes and, apart, the agents of each.
fn csba_wls_parts(p: &CsbaParams, agents: &[Vec<Detection>]) -> (Vec<Detection>, Vec<AgentSet>) {
    let (fused, groups) = csba_groups(p, agents);
    let sources = groups
        .iter()
        .map(|g| g.iter().map(|&(k, _)| k).collect())
        .collect();
    (fused, sources)
}

pub use crate::maths::parts::Members;

/// CSBA-3D association and WLS-3D fusion ([`csba_wls`]): the fused boxes and the members of
/// each, in the same order.
pub fn csba_groups(p: &CsbaParams, agents: &[Vec<Detection>]) -> (Vec<Detection>, Vec<Members>) {
    in_parts(p, agents, |a| csba_one_pass(p, a)).unwrap_or_else(|| csba_one_pass(p, agents))
}

/// [`csba_groups`] in one pass over the agents' lists.
fn csba_one_pass<D: Borrow<Detection>>(
    p: &CsbaParams,
    agents: &[Vec<D>],
) -> (Vec<Detection>, Vec<Members>) {
    let n: usize = agents.iter().map(Vec::len).sum();
    let mut groups: Vec<Members> = Vec::with_capacity(n);
    // Each group's WLS-3D sums once it has two members: a member joining adds its own terms.
    let mut sums: Vec<Option<GroupSum>> = Vec::with_capacity(n);
    let member = |&(k, j): &(usize, usize)| agents[k][j].borrow();
    let sum_of = |g: &Members| {
        let refs: smallvec::SmallVec<[&Detection; 4]> = g.iter().map(member).collect();
        GroupSum::of(&refs)
    };
    // The running fused boxes. Until a second agent's boxes arrive they are the first agent's
    // list itself (`base`), copied once, with its groups already re-fused, when they do.
    let mut fused: Vec<Detection> = Vec::new();
    let mut base: Option<&[D]> = None;
    for (k, list) in agents.iter().enumerate() {
        if list.is_empty() {
            continue;
        }
        let pairs: Vec<(usize, usize)> = match (base, fused.is_empty()) {
            (None, true) => {
                base = Some(list);
                groups.extend((0..list.len()).map(|j| smallvec::smallvec![(k, j)]));
                sums.resize(groups.len(), None);
                continue;
            }
            (Some(first), _) => consistent_pairs(p, first, list),
            (None, false) => consistent_pairs(p, &fused, list),
        };
        let mut taken = vec![false; list.len()];
        for &(g, j) in &pairs {
            taken[j] = true;
            groups[g].push((k, j));
        }
        if let Some(first) = base.take() {
            fused.reserve(n);
            for (g, d) in first.iter().enumerate() {
                if groups[g].len() > 1 {
                    let sum = sum_of(&groups[g]);
                    fused.push(sum.fused());
                    sums[g] = Some(sum);
                } else {
                    fused.push(d.borrow().clone());
                }
            }
        } else {
            for &(g, j) in &pairs {
                let sum = match &mut sums[g] {
                    Some(sum) => {
                        sum.add(list[j].borrow());
                        sum
                    }
                    slot => slot.insert(sum_of(&groups[g])),
                };
                fused[g] = sum.fused();
            }
        }
        for (j, d) in list.iter().enumerate() {
            if !taken[j] {
                groups.push(smallvec::smallvec![(k, j)]);
                sums.push(None);
                fused.push(d.borrow().clone());
            }
        }
    }
    if let Some(first) = base {
        fused = first.iter().map(|d| d.borrow().clone()).collect();
    }
    (fused, groups)
}

/// CSBA-3D's pairs of the running boxes `current` and an agent's `list` that pass [`consistent`].
fn consistent_pairs<A, B>(p: &CsbaParams, current: &[A], list: &[B]) -> Vec<(usize, usize)>
where
    A: Borrow<Detection>,
    B: Borrow<Detection>,
{
    associate(p, current, list)
        .into_iter()
        .filter(|&(g, j)| consistent(p, current[g].borrow(), list[j].borrow()))
        .collect()
}

/// The chi-square test of a new member against its group's fused box: its squared centre
/// Mahalanobis distance (with the group's fused and the member's own covariance) within the
/// bound of `p.consistency`.
pub fn consistent(p: &CsbaParams, group: &Detection, member: &Detection) -> bool {
    p.consistency
        .is_none_or(|bound| mahalanobis(group, member).powi(2) <= bound)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn det(x: f64, y: f64, s: f64, id: u32) -> Detection {
        Detection {
            yaw: 0.3,
            score: 0.7,
            id,
            ..v2x_protocol::fixtures::car(x, y, s)
        }
    }

    #[test]
    fn names_round_trip() {
        for n in METHODS {
            let m = Method::parse_any(n.name).unwrap();
            assert_eq!((m, m.name()), (n.method, n.name.to_string()));
        }
        // Every registered method is a different one.
        let all = Method::all_with_ablations();
        for (i, m) in all.iter().enumerate() {
            assert!(!all[..i].contains(m), "{m} registered twice");
        }
        let e = "kalman".parse::<Method>().unwrap_err();
        assert_eq!(e.given, "kalman");
        assert!(e.expected.contains(&"csba-wls+"));
        // An ablation is a bench row: only parse_any takes it, and `all` leaves it out.
        let e = "csba-wls+gate".parse::<Method>().unwrap_err();
        assert!(!e.expected.contains(&"csba-wls+gate"));
        let gate = Method::parse_any("csba-wls+gate").unwrap();
        assert_eq!(gate.name(), "csba-wls+gate");
        assert!(!Method::all().contains(&gate) && all.contains(&gate));
        assert_eq!(Method::all().len(), all.len() - 4);
    }

    #[test]
    fn the_velocity_gate_keeps_cars_passing_each_other_apart() {
        // Two cars 2 m apart driving opposite ways, seen by two agents with 3 m of position
        // noise: agent 2's boxes lie nearer the other car. csba-wls+ pairs by place and fuses
        // each car with the other (velocities averaged to 0); csba-wls+vel finds the pairs'
        // velocities 200 (dv^2 = 20^2 / 2) beyond its gate and pairs each car with itself.
        let car = |x: f64, vy: f64, id: u32| Detection {
            velocity: Some(v2x_protocol::Velocity {
                v: [0.0, vy],
                std: [1.0; 2],
            }),
            ..det(x, 0.0, 3.0, id)
        };
        let a1 = vec![car(0.0, 10.0, 1), car(2.0, -10.0, 2)];
        let a2 = vec![car(2.2, 10.0, 1), car(-0.2, -10.0, 2)];
        let vy = |out: &[Detection]| -> Vec<f64> {
            let mut v: Vec<f64> = out
                .iter()
                .map(|d| d.velocity.as_ref().unwrap().v[1])
                .collect();
            v.sort_by(f64::total_cmp);
            v
        };
        let plain = Method::Csba(CsbaParams::PLUS).fuse(&[a1.clone(), a2.clone()]);
        assert_eq!(vy(&plain), vec![0.0, 0.0]);
        let gated: Method = "csba-wls+vel".parse().unwrap();
        let out = gated.fuse(&[a1, a2]);
        assert_eq!(vy(&out), vec![-10.0, 10.0]);
        for d in &out {
            // Each car's two boxes: x = (0 + 2.2) / 2 and (2 - 0.2) / 2.
            let x = if d.id == 1 { 1.1 } else { 0.9 };
            assert!((d.center[0] - x).abs() < 1e-9, "{d:?}");
        }
    }

    #[test]
    fn three_agents_sequential() {
        // Two objects seen by three agents; agent 3 is the most certain and lends its ids.
        let a1 = vec![det(0.0, 0.0, 0.5, 1), det(20.0, 0.0, 0.5, 2)];
        let a2 = vec![det(20.6, 0.0, 0.5, 2), det(0.3, 0.0, 0.5, 1)];
        let a3 = vec![det(0.0, 0.3, 0.25, 101), det(30.0, 0.0, 0.25, 103)];
        for m in [
            Method::Csba(CsbaParams::PAPER),
            Method::Csba(CsbaParams::PLUS),
        ] {
            let out = m.fuse(&[a1.clone(), a2.clone(), a3.clone()]);
            assert_eq!(out.len(), 3, "{m}");
            // object 1: weights 4, 4, 16 -> x = (0 + 0.3*4/4... ) = (0*4 + 0.3*4 + 0*16)/24 = 0.05
            assert!((out[0].center[0] - 0.05).abs() < 1e-9);
            assert!((out[0].center[1] - 0.2).abs() < 1e-9);
            assert_eq!(out[0].id, 101);
            assert!((out[0].std.pos[0] - (1.0f64 / 24.0).sqrt()).abs() < 1e-9);
            assert!((out[1].center[0] - 20.3).abs() < 1e-9);
            assert_eq!(out[1].id, 2);
            assert_eq!(out[2].id, 103);
            let sources: Vec<Vec<usize>> = m
                .fuse_sourced(&[a1.clone(), a2.clone(), a3.clone()])
                .iter()
                .map(|s| s.sources.iter().collect())
                .collect();
            assert_eq!(sources, vec![vec![0, 1, 2], vec![0, 1], vec![2]], "{m}");
        }
    }

    #[test]
    fn every_method_names_the_agents_of_each_box() {
        // One object seen by both agents (1 cm apart, same box), one by agent 1 alone far away.
        let a = vec![det(0.0, 0.0, 0.5, 1)];
        let b = vec![det(0.01, 0.0, 0.5, 1), det(60.0, 0.0, 0.5, 2)];
        for m in Method::all() {
            let out = m.fuse_sourced(&[a.clone(), b.clone()]);
            let mut sources: Vec<Vec<usize>> =
                out.iter().map(|s| s.sources.iter().collect()).collect();
            sources.sort();
            assert_eq!(sources, vec![vec![0, 1], vec![1]], "{m}");
            let far = out.iter().find(|s| s.det.center[0] > 30.0).unwrap();
            assert_eq!(far.sources, AgentSet::single(1), "{m}");
            assert_eq!(
                m.fuse(&[a.clone(), b.clone()]),
                out.into_iter().map(|s| s.det).collect::<Vec<_>>()
            );
        }
    }

    #[test]
    fn unmatched_are_kept() {
        let out = Method::Csba(CsbaParams::PAPER).fuse(&[
            vec![det(0.0, 0.0, 0.5, 1)],
            vec![det(50.0, 0.0, 0.5, 2)],
            vec![],
        ]);
        assert_eq!(out.len(), 2);
        assert!(Method::Csba(CsbaParams::PAPER).fuse(&[]).is_empty());
    }
}

/// A large window split into parts ([`in_parts`]) fuses as one pass does.
#[cfg(test)]
mod parts_tests {
    use super::*;
    use crate::maths::association::{Gate, Spread};
    use crate::maths::parts::PARALLEL_FROM;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use v2x_protocol::fixtures::{car, URBAN_MIX};

    /// `agents` noisy views of `n` objects of the urban mix within `half` m of the origin (1 m
    /// position std, up to `off` m off in x, 1.5 m in y).
    fn window(n: usize, agents: usize, half: f64, off: f64, seed: u64) -> Vec<Vec<Detection>> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let truth: Vec<Detection> = (0..n)
            .map(|i| {
                let mut d = car(rng.gen_range(-half..half), rng.gen_range(-half..half), 1.0);
                d.class = URBAN_MIX[i % URBAN_MIX.len()];
                d.size = d.class.typical_size();
                d
            })
            .collect();
        (0..agents)
            .map(|_| {
                let mut seen = Vec::new();
                for d in &truth {
                    if rng.gen_bool(0.9) {
                        let mut d = d.clone();
                        d.center[0] += rng.gen_range(-off..off);
                        d.center[1] += rng.gen_range(-1.5..1.5);
                        seen.push(d);
                    }
                }
                seen
            })
            .collect()
    }

    fn pool(threads: usize) -> rayon::ThreadPool {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
    }

    #[test]
    fn a_window_fused_in_parts_equals_one_pass() {
        let mahalanobis = CsbaParams {
            gate: Gate::Mahalanobis { lambda: 4.0 },
            ..CsbaParams::PLUS
        };
        let (one, two) = (pool(1), pool(2));
        for p in [CsbaParams::default(), CsbaParams::PLUS, mahalanobis] {
            // Dense and sparse; the last with pairs up to 8 m apart in x and little between
            // them, near the default gate's reach (6 x 1 m x sqrt 2).
            let windows = [
                (300, 16, 300.0, 1.5),
                (300, 16, 60.0, 1.5),
                (2500, 2, 3000.0, 4.0),
            ];
            for (seed, &(n, agents, half, off)) in (1..).zip(&windows) {
                let agents = window(n, agents, half, off, seed);
                assert!(agents.iter().map(Vec::len).sum::<usize>() >= PARALLEL_FROM);
                let one_pass = |a: &[Vec<&Detection>]| one.install(|| csba_one_pass(&p, a));
                let split = two
                    .install(|| in_parts(&p, &agents, one_pass))
                    .expect("split");
                let whole = one.install(|| csba_groups(&p, &agents));
                assert_eq!(split.1, whole.1, "{p:?} seed {seed}");
                assert_eq!(split.0, whole.0, "{p:?} seed {seed}");
                let span = agents.len().min(9);
                assert!(
                    whole.1.iter().any(|g| g.len() >= span),
                    "groups span agents"
                );
                // Through the method itself, on both threads.
                assert_eq!(two.install(|| csba_groups(&p, &agents)), whole);
            }
        }
        // A full covariance: cut by class alone, still the one pass's groups.
        let mut agents = window(300, 16, 60.0, 1.5, 4);
        agents[3][0].pos_cov = Some(Box::new([
            [1.0, 0.2, 0.0],
            [0.2, 1.0, 0.0],
            [0.0, 0.0, 1.0],
        ]));
        let p = CsbaParams::PLUS;
        let mut spread = Spread::default();
        agents.iter().flatten().for_each(|d| spread.add(d));
        assert_eq!(spread.x_reach(&p), None);
        let whole = one.install(|| csba_groups(&p, &agents));
        assert_eq!(two.install(|| csba_groups(&p, &agents)), whole);
        // Below the bound, or with one thread, there is no split.
        let one_pass = |a: &[Vec<&Detection>]| csba_one_pass(&p, a);
        let small = window(100, 4, 300.0, 1.5, 3);
        assert!(two.install(|| in_parts(&p, &small, one_pass)).is_none());
        let large = window(300, 16, 300.0, 1.5, 1);
        assert!(one.install(|| in_parts(&p, &large, one_pass)).is_none());
    }
}
