use super::*;
use crate::scenario::Scenario;

fn scenario(events: &str) -> Result<Scenario, String> {
    let text = format!(
        r#"
duration_s = 20.0
[[agents]]
name = "veh"
noise = "mild"
link = {{ latency_ms = 5.0 }}
[[agents]]
name = "rsu"
kind = "infrastructure"
noise = "mild"
{events}
"#
    );
    Scenario::parse(&text, "test.toml", None).map_err(|e| format!("{e:#}"))
}

#[test]
fn events_parse_and_each_error_names_its_event() {
    let s = scenario(
        r#"
[[events]]
at_s = 8.0
target = "rsu"
action = "leave"
[[events]]
at_s = 12.0
target = "veh"
action = "link"
latency_ms = 80.0
jitter_ms = 10.0
[[events]]
at_s = 15.0
target = "veh"
action = "clock_jump"
jump_ms = -250.0
"#,
    )
    .unwrap();
    assert_eq!(s.events.len(), 3);
    assert_eq!(s.events[1].action, Action::Link);
    let err = |text: &str| scenario(text).unwrap_err();
    let e = err("[[events]]\nat_s = 3.0\ntarget = \"bus\"\naction = \"leave\"");
    assert!(
        e.contains("events[0] (at_s 3, bus): no agent of that name (agents: veh, rsu)"),
        "{e}"
    );
    let e = err("[[events]]\nat_s = 30.0\ntarget = \"veh\"\naction = \"leave\"");
    assert!(
        e.contains("events[0]") && e.contains("within the run"),
        "{e}"
    );
    let e = err("[[events]]\nat_s = 3.0\ntarget = \"veh\"\naction = \"leave\"\njump_ms = 3.0");
    assert!(e.contains("jump_ms does not apply to Leave"), "{e}");
    let e = err("[[events]]\nat_s = 3.0\ntarget = \"veh\"\naction = \"join\"");
    assert!(e.contains("already there"), "{e}");
    let e = err("[[events]]\nat_s = 3.0\ntarget = \"veh\"\naction = \"link\"\ndrop_rate = 1.5");
    assert!(e.contains("events[0]") && e.contains("drop_rate"), "{e}");
    let e = err("[[events]]\nat_s = 3.0\ntarget = \"veh\"\naction = \"link\"");
    assert!(e.contains("link needs"), "{e}");
    let e = err("[[events]]\nat_s = 3.0\ntarget = \"veh\"\naction = \"loss_burst\"");
    assert!(e.contains("duration_s > 0"), "{e}");
    let e = err("[[events]]\nat_s = 3.0\ntarget = \"veh\"\naction = \"noise\"\nnoise = \"huge\"");
    assert!(e.contains("events[0]") && e.contains("noise"), "{e}");
    let e = err("[[events]]\nat_s = 3.0\ntarget = \"veh\"\naction = \"explode\"");
    assert!(e.contains("explode"), "{e}");
    // leaving twice, in time order whatever the file order
    let e = err("[[events]]\nat_s = 9.0\ntarget = \"veh\"\naction = \"leave\"\n[[events]]\nat_s = 3.0\ntarget = \"veh\"\naction = \"leave\"");
    assert!(
        e.contains("events[0] (at_s 9, veh): the agent has already left"),
        "{e}"
    );
}

#[test]
fn an_agents_state_follows_its_events() {
    let s = scenario(
        r#"
[[events]]
at_s = 2.0
target = "veh"
action = "leave"
[[events]]
at_s = 4.0
target = "veh"
action = "join"
[[events]]
at_s = 5.0
target = "veh"
action = "loss_burst"
duration_s = 1.0
[[events]]
at_s = 5.5
target = "veh"
action = "link"
latency_ms = 80.0
drop_rate = 0.25
[[events]]
at_s = 7.0
target = "veh"
action = "clock_jump"
jump_ms = 300.0
[[events]]
at_s = 8.0
target = "veh"
action = "clock_jump"
jump_ms = -100.0
[[events]]
at_s = 9.0
target = "veh"
action = "noise"
noise = "large"
faults = "fp=2"
[[events]]
at_s = 1.0
target = "rsu"
action = "leave"
"#,
    )
    .unwrap();
    let mut t = s.agents[0].timeline(&s.events);
    let s_ = |x: f64| (x * 1e6) as u64;
    let st = t.at(s_(1.9));
    assert!(st.present);
    assert_eq!(st.link.latency_ms, 5.0);
    assert!(!t.at(s_(2.0)).present, "due at 2.0 s exactly");
    assert!(!t.at(s_(3.9)).present);
    assert!(t.at(s_(4.0)).present);
    assert_eq!(t.at(s_(5.2)).link.drop_rate, 1.0, "inside the burst");
    let st = t.at(s_(5.7));
    assert_eq!(
        (st.link.latency_ms, st.link.drop_rate),
        (80.0, 1.0),
        "the burst outlasts the link change"
    );
    let st = t.at(s_(6.0));
    assert_eq!(
        (st.link.latency_ms, st.link.jitter_ms, st.link.drop_rate),
        (80.0, 0.0, 0.25)
    );
    assert_eq!(t.at(s_(7.5)).link.clock_offset_ms, 300.0);
    assert_eq!(t.at(s_(8.5)).link.clock_offset_ms, 200.0);
    let st = t.at(s_(9.0));
    assert_eq!(
        st.noise,
        "large"
            .parse::<AgentNoise>()
            .map(|mut n| {
                n.faults = "fp=2".parse().unwrap();
                n
            })
            .unwrap()
    );
    // the other agent only sees its own events
    let mut rsu = s.agents[1].timeline(&s.events);
    assert!(rsu.at(s_(0.5)).present);
    assert!(!rsu.at(s_(19.0)).present);
}

#[test]
fn the_fuser_can_only_restart() {
    let s = scenario(
        "[[events]]\nat_s = 9.0\ntarget = \"fuser\"\naction = \"restart\"\nduration_s = 1.5\n[[events]]\nat_s = 4.0\ntarget = \"fuser\"\naction = \"restart\"",
    )
    .unwrap();
    assert_eq!(
        fuser_restarts(&s.events),
        vec![(4_000_000, 0), (9_000_000, 1_500_000)]
    );
    let err = |text: &str| scenario(text).unwrap_err();
    let e = err("[[events]]\nat_s = 3.0\ntarget = \"fuser\"\naction = \"leave\"");
    assert!(
        e.contains("events[0] (at_s 3, fuser): the fuser can only restart, not Leave"),
        "{e}"
    );
    let e = err("[[events]]\nat_s = 3.0\ntarget = \"veh\"\naction = \"restart\"");
    assert!(e.contains("restart applies to the target fuser"), "{e}");
    let e =
        err("[[events]]\nat_s = 3.0\ntarget = \"fuser\"\naction = \"restart\"\nduration_s = -1.0");
    assert!(e.contains("duration_s must be 0 or more"), "{e}");
    let e = err("[[events]]\nat_s = 3.0\ntarget = \"fuser\"\naction = \"restart\"\njump_ms = 1.0");
    assert!(e.contains("jump_ms does not apply to Restart"), "{e}");
    // an agent's timeline ignores the fuser's events
    let mut t = s.agents[0].timeline(&s.events);
    assert!(t.at(10_000_000).present);
}
