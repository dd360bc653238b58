//! Ctrl-C during `ember render`: the completed passes are written as `<stem>_partial_<N>spp.exr`
//! (atomically, never a corrupt file), the exit status is 130, and the partial image is bit for
//! bit the image of an uninterrupted `N` spp render.

mod cli_util;
mod common;

use cli_util::{ember, TempDir};
use common::*;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const SPP: u32 = 16_000;
/// `pass_size` in host-cli/src/render.rs: spp/16 (above its minimum of 8 for path tracers).
const PASS: u32 = SPP / 16;

/// Runs a long render and interrupts it after `wait`; returns (exit code, stderr).
fn interrupted_run(
    scene: &std::path::Path,
    out: &std::path::Path,
    wait: Duration,
) -> (Option<i32>, String) {
    let child = Command::new(ember())
        .arg("render")
        .arg(scene)
        .args([
            "-o",
            out.to_str().unwrap(),
            "-q",
            "--width",
            "32",
            "--height",
            "32",
        ])
        // Independent samples: with them a render's first N samples are the N-spp render
        // (ZSobol lays its samples out for the whole --spp).
        .args(["--spp", &SPP.to_string(), "--threads", "2"])
        .args(["--sampler", "independent"])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(wait);
    let status = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    let start = Instant::now();
    let output = child.wait_with_output().unwrap();
    assert!(
        start.elapsed() < Duration::from_secs(60),
        "interrupt took too long"
    );
    (
        output.status.code(),
        String::from_utf8_lossy(&output.stderr).into_owned(),
    )
}

#[test]
fn interrupted_render_writes_the_completed_passes() {
    let dir = TempDir::new("interrupt");
    let scene = project_data("cornell-box/cornell_box.toml");
    let out = dir.path().join("cb.exr");
    // Wait long enough for at least one pass; on a loaded machine, wait longer and retry.
    let mut attempt = None;
    for wait_ms in [3_000, 10_000, 30_000] {
        let (code, stderr) = interrupted_run(&scene, &out, Duration::from_millis(wait_ms));
        assert_eq!(code, Some(130), "stderr: {stderr}");
        if !stderr.contains("before the first pass finished") {
            attempt = Some(stderr);
            break;
        }
        assert!(
            dir.outputs().is_empty(),
            "an interrupted first pass wrote files"
        );
    }
    let stderr = attempt.expect("no pass finished even after 30 s");
    assert!(
        !out.exists(),
        "the full-render name must not be used for a partial image"
    );
    let files = dir.outputs();
    let partial = files
        .iter()
        .find(|p| p.extension().is_some_and(|e| e == "exr"))
        .unwrap_or_else(|| panic!("no partial EXR written; stderr: {stderr}; files {files:?}"));
    assert!(
        files.iter().all(|p| !p.to_string_lossy().ends_with(".tmp")),
        "temporary file left behind: {files:?}"
    );
    let name = partial.file_name().unwrap().to_string_lossy().into_owned();
    let spp: u32 = name
        .strip_prefix("cb_partial_")
        .and_then(|s| s.strip_suffix("spp.exr"))
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("unexpected partial name {name}"));
    assert!(
        spp > 0 && spp < SPP && spp.is_multiple_of(PASS),
        "{spp} spp"
    );
    assert!(stderr.contains(&format!("interrupted after {spp} of {SPP} spp")));

    let written = ember_cli::image::read_exr(partial).unwrap();
    let direct = render_scene_with(
        &scene,
        32,
        32,
        spp,
        ember_kernel::sampler::DEFAULT_SEED,
        16,
        2,
    );
    let bits = |px: &[glam::Vec3]| -> Vec<u32> {
        px.iter()
            .flat_map(|p| p.to_array().map(f32::to_bits))
            .collect()
    };
    // SPP in passes of PASS and `spp` in passes of spp/16 add the same samples in the same
    // order, so the images agree to the bit.
    assert_eq!(bits(&written.pixels), bits(&direct.image.pixels));
}
