//! `scenarios/city.toml` in one process: four regional fusers over two meshed routers score as
//! one fuser on the same data, and track as it does (their tracks handed over at the borders). (A file of its own: its many sessions would slow the other
//! region tests running beside it.)

use v2x_tests::within;

/// `scenarios/city.toml`, shortened to `seconds`.
fn city(seconds: f64) -> v2x_sim::scenario::Scenario {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/city.toml");
    let mut s = v2x_sim::scenario::Scenario::load(&path).unwrap();
    s.duration_s = seconds;
    s.dataset.seconds = seconds;
    s.namespace = format!("city-{seconds}");
    s
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn a_city_of_four_regions_scores_as_one_fuser() {
    let mut scenario = city(4.0);
    scenario.fuser.settings.track = true;
    let gt = scenario.dataset.data_args().load().unwrap();
    let (_keep, stop) = tokio::sync::watch::channel(false);
    let (city, outcome, regions) = within(
        90,
        "the city run",
        v2x_sim::run::city::run_city_local(&scenario, &gt, stop),
    )
    .await
    .unwrap();
    let mut single_scenario = scenario.clone();
    single_scenario.regions = None;
    single_scenario.namespace.push_str("-single");
    let (single, _) = within(
        90,
        "the single-fuser run",
        v2x_sim::run::run_local(&single_scenario, &gt),
    )
    .await
    .unwrap();
    // Four regions, each heard from, together publishing every fused box once.
    assert_eq!(regions.len(), 4);
    let published: u64 = regions.iter().map(|r| r.fused_objects).sum();
    let boxes: usize = outcome.fused.values().map(Vec::len).sum();
    assert_eq!(published as usize, boxes);
    assert!(
        regions
            .iter()
            .all(|r| r.fused_objects > 0 && r.captures_incomplete == 0),
        "{regions:#?}"
    );
    assert_eq!(city.frames_scheduled, 40);
    assert!(city.windows >= 38, "{} windows", city.windows);
    // The same metrics as one fuser on the same data, within the noise of two live runs (a late
    // frame here or there).
    let (c, s) = (&city.fused, &single.fused);
    let d = |a: Option<f64>, b: Option<f64>| (a.unwrap() - b.unwrap()).abs();
    assert!(
        d(c.precision, s.precision) <= 0.01,
        "precision {c:?} vs {s:?}"
    );
    assert!(d(c.recall, s.recall) <= 0.03, "recall {c:?} vs {s:?}");
    assert!(d(c.all.m_ate, s.all.m_ate) <= 0.05, "mATE {c:?} vs {s:?}");
    // Better than any agent alone, as fusion should be.
    let best_alone = city
        .agents
        .values()
        .filter_map(|m| m.recall)
        .fold(0.0, f64::max);
    assert!(c.recall.unwrap() > best_alone);
    // Tracks: the regions hand them over at the borders, so the city's identities switch about
    // as often as one fuser's.
    let (ct, st) = (city.tracking.unwrap(), single.tracking.unwrap());
    eprintln!("city {ct:?}\nsingle {st:?}");
    assert!(
        ct.ids <= st.ids + 3,
        "IDS city {} vs single {}",
        ct.ids,
        st.ids
    );
    assert!(
        (ct.amota - st.amota).abs() <= 0.05,
        "AMOTA {ct:?} vs {st:?}"
    );
}
