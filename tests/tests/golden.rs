//! The determinism scene's hashes equal the committed golden ones (tests/golden/determinism.txt).
//! scripts/determinism.sh checks the same hashes on every build configuration and target.

use std::path::Path;

fn golden(name: &str) -> u64 {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("golden/determinism.txt");
    let text = std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    text.lines()
        .filter(|l| !l.starts_with('#'))
        .find_map(|l| {
            let (key, hex) = l.split_once(' ')?;
            (key == name).then(|| u64::from_str_radix(hex.trim(), 16).ok())?
        })
        .unwrap_or_else(|| panic!("no `{name} <hex>` line in {}", path.display()))
}

#[test]
fn determinism_scene_matches_the_golden_hashes() {
    let h = ember_determinism::hashes();
    let (render, bake, splat) = (golden("render"), golden("bake"), golden("splat"));
    assert!(
        h.render == render && h.bake == bake && h.splat == splat,
        "the determinism scene's images changed:\n  render {:016x} (golden {render:016x})\n  \
         bake   {:016x} (golden {bake:016x})\n  splat  {:016x} (golden {splat:016x})\nIf the \
         change is intended, put the new hashes in tests/golden/determinism.txt in the same \
         commit and say in its message why the images changed; then run \
         scripts/determinism.sh to check every target agrees.",
        h.render,
        h.bake,
        h.splat
    );
}

/// The bake's settings turn on the kernel shortcuts; they must be ones the scene allows, or the
/// unchanged bake hash would say nothing about them.
#[test]
fn determinism_bake_uses_the_shortcuts_its_scene_allows() {
    let scene = ember_determinism::Scene::new();
    let allowed = ember_kernel::integrator::Shortcuts::analyse(&scene.view());
    assert_eq!(ember_determinism::BAKE_PATH.shortcuts, allowed);
    assert!(allowed.terminal_emitter_test);
}
