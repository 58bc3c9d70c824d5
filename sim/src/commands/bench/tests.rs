use super::*;
use clap::Parser;

#[derive(Parser)]
struct Cli {
    #[command(flatten)]
    bench: BenchArgs,
}

fn parse(flags: &[&str]) -> Result<BenchArgs, clap::Error> {
    Cli::try_parse_from(std::iter::once("bench").chain(flags.iter().copied())).map(|c| c.bench)
}

fn refused(flags: &[&str]) -> String {
    crate::sources::bench(parse(flags).unwrap())
        .unwrap_err()
        .to_string()
}

#[test]
fn each_mode_takes_its_own_options_and_real_data_runs_its_own_tables() {
    assert!(parse(&[]).unwrap().mode.is_none());
    let modes = [
        (&["tracking"][..], "tracking"),
        (&["tracking", "--seeds", "1,2", "--parts", "2"], "tracking"),
        (
            &["detection", "--profile", "realistic", "--align"],
            "detection",
        ),
        (&["regions", "--tile-size", "50", "--tracking"], "regions"),
        (&["async", "--noise", "mild"], "async"),
    ];
    for (flags, name) in modes {
        let got = match parse(flags).unwrap().mode.unwrap() {
            BenchMode::Tracking(_) => "tracking",
            BenchMode::Detection(_) => "detection",
            BenchMode::Regions(_) => "regions",
            BenchMode::Async(_) => "async",
        };
        assert_eq!(got, name, "{flags:?}");
    }
    // An option is taken only where it means something: no refusal list, clap says no.
    for bad in [
        &["--tracking"][..],
        &["tracking", "--agents", "4"],
        &["async", "--profile", "realistic"],
        &["detection"],
        &["--agents", "4", "tracking"],
        &["tracking", "--parts", "2"],
        &["tracking", "--town-seeds", "7"],
        &["tracking", "--seeds", "1", "--parts", "17"],
        &["tracking", "--seeds", "1", "--more-dataroot", "b"],
        &[
            "tracking",
            "--seeds",
            "1",
            "--dataroot",
            "a",
            "--town-seeds",
            "7",
        ],
        &["tracking", "--association", "guided"],
        &["--agents", "65"],
        &["--agents", "0"],
    ] {
        assert!(parse(bad).is_err(), "{bad:?}");
    }
    assert_eq!(parse(&["--agents", "64"]).unwrap().table.agents, 64);
    // The regions need their tiles' side; a bad one is named before any data is read.
    assert!(refused(&["regions"]).contains("give --tile-size"));
    let err = parse(&["regions", "--tile-size", "0.5"])
        .err()
        .unwrap()
        .to_string();
    assert!(err.contains("at least 1 m"), "{err}");
    let err = parse(&["regions", "--tile-size", "50", "--halo=-1"])
        .err()
        .unwrap()
        .to_string();
    assert!(err.contains("halo -1 m"), "{err}");
    // The real data sets: their own tables, with their own two agents.
    let v2v = ["--dataset", "v2v4real", "--dataroot", "x"];
    for mode in [
        &["tracking"][..],
        &["regions", "--tile-size", "50"],
        &["async"],
    ] {
        let err = refused(&[mode, &v2v[..]].concat());
        assert!(
            err.contains("--dataset v2v4real runs its own tables"),
            "{err}"
        );
    }
    let err = refused(&["tracking", "--dataset", "dair-v2x", "--dataroot", "x"]);
    assert!(
        err.contains("--dataset dair-v2x runs its own tables"),
        "{err}"
    );
    let err = refused(&[&v2v[..], &["--agents", "4"]].concat());
    assert!(err.contains("real data sets have their own two"), "{err}");
}

#[test]
fn logs_and_parts_go_with_the_seeds_and_the_town_seeds_with_the_town() {
    for extra in [
        &["--parts", "2"][..],
        &["--town-seeds", "7,8"],
        &[
            "--dataroot",
            "a",
            "--more-dataroot",
            "b",
            "--more-dataroot",
            "c",
        ],
    ] {
        let flags = [&["tracking", "--seeds", "1,2"][..], extra].concat();
        assert!(parse(&flags).is_ok(), "{flags:?}");
    }
    let flags = [
        "tracking",
        "--seeds",
        "1",
        "--town-seeds",
        "7,9",
        "--parts",
        "2",
        "--seconds",
        "2",
    ];
    let Some(BenchMode::Tracking(args)) = parse(&flags).unwrap().mode else {
        panic!("tracking");
    };
    let logs = tracking::tracking_logs(&args).unwrap();
    let names: Vec<&str> = logs.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names.len(), 4);
    assert!(names[0].starts_with("synthetic town (seed 7,"), "{names:?}");
    assert!(names[1].contains("part 2 of 2: 10 frames"), "{names:?}");
    assert!(names[3].starts_with("synthetic town (seed 9,"), "{names:?}");
}
