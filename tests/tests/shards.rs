//! Renders split across processes: the local example script with 3 shards, merged, is bit for
//! bit the single render; parts of different renders and missing shards are refused.

mod cli_util;
mod common;

use cli_util::{ember, run_ember, TempDir};
use common::*;
use std::process::Command;

fn bits(path: &std::path::Path) -> Vec<u32> {
    ember_cli::image::read_exr(path)
        .unwrap()
        .pixels
        .iter()
        .flat_map(|p| p.to_array().map(f32::to_bits))
        .collect()
}

#[test]
fn three_local_shards_merge_to_the_single_render() {
    let dir = TempDir::new("shards");
    let scene = project_data("cornell-box/cornell_box.toml");
    let opts = [
        "--spp", "4", "--width", "53", "--height", "37", "--tile", "8",
    ];
    let single = dir.path().join("single.exr");
    let out = run_ember(
        [
            "render",
            scene.to_str().unwrap(),
            "-q",
            "-o",
            single.to_str().unwrap(),
        ]
        .iter()
        .chain(opts.iter()),
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );

    let merged = dir.path().join("merged.exr");
    let script =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scripts/distributed/local.sh");
    let status = Command::new("bash")
        .arg(&script)
        .arg(&scene)
        .arg("3")
        .arg(&merged)
        .args(opts)
        .env("EMBER", ember())
        .status()
        .unwrap();
    assert!(status.success());
    assert_eq!(
        bits(&merged),
        bits(&single),
        "merged shards differ from the single render"
    );
}

#[test]
fn merge_refuses_incomplete_or_mixed_parts() {
    let dir = TempDir::new("shards-bad");
    let scene = project_data("cornell-box/cornell_box.toml");
    let part = |i: u32, n: u32, spp: &str| {
        let p = dir.path().join(format!("p{i}of{n}s{spp}.exr"));
        let out = run_ember([
            "render",
            scene.to_str().unwrap(),
            "-q",
            "--width",
            "16",
            "--height",
            "16",
            "--tile",
            "4",
            "--spp",
            spp,
            "--shard",
            &format!("{i}/{n}"),
            "-o",
            p.to_str().unwrap(),
        ]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        p
    };
    let (a, b, c) = (part(0, 2, "1"), part(1, 2, "1"), part(1, 2, "2"));
    let merged = dir.path().join("m.exr");
    let m = merged.to_str().unwrap();
    let missing = run_ember(["merge", a.to_str().unwrap(), "-o", m]);
    assert_eq!(missing.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&missing.stderr).contains("shard 1/2 is missing"));
    let mixed = run_ember(["merge", a.to_str().unwrap(), c.to_str().unwrap(), "-o", m]);
    assert_eq!(mixed.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&mixed.stderr).contains("different render"));
    let twice = run_ember(["merge", a.to_str().unwrap(), a.to_str().unwrap(), "-o", m]);
    assert_eq!(twice.status.code(), Some(2));
    assert!(!merged.exists());
    let ok = run_ember(["merge", a.to_str().unwrap(), b.to_str().unwrap(), "-o", m]);
    assert!(
        ok.status.success(),
        "{}",
        String::from_utf8_lossy(&ok.stderr)
    );
    let bad = run_ember(["render", scene.to_str().unwrap(), "--shard", "2/2"]);
    assert_eq!(bad.status.code(), Some(2));
}
