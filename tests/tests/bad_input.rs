//! Bad input to the `ember` binary: every case must exit with status 2, print one line
//! `error: <file>: <what is wrong>` naming the offending file and the problem, never panic, and
//! leave no output image (nor a temporary file of the atomic write) behind.
//!
//! Run with `-- --nocapture` to see the exact stderr line of every case.

mod cli_util;

use cli_util::{edit, run_ember, TempDir, QUAD_MTL, QUAD_OBJ, SCENE_TOML};
use std::path::{Path, PathBuf};
use std::process::Output;

/// A case directory holding `scene.toml`, `quad.obj` and `quad.mtl`.
fn scene_dir(name: &str, toml: &str, obj: &str, mtl: &str) -> (TempDir, PathBuf) {
    let dir = TempDir::new(name);
    let scene = dir.write("scene.toml", toml);
    dir.write("quad.obj", obj);
    dir.write("quad.mtl", mtl);
    (dir, scene)
}

/// `ember render SCENE -q` plus `extra` arguments.
fn render(scene: &Path, extra: &[&str]) -> Output {
    let mut args: Vec<std::ffi::OsString> = vec!["render".into(), scene.into(), "-q".into()];
    args.extend(extra.iter().map(Into::into));
    run_ember(args)
}

/// Checks the bad-input contract and prints the error line (see it with `--nocapture`).
#[track_caller]
fn assert_bad_input(case: &str, out: &Output, dir: &TempDir, file: &str, phrases: &[&str]) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    let stdout = String::from_utf8_lossy(&out.stdout);
    let ctx = format!("case {case}\n--- stderr:\n{stderr}--- stdout:\n{stdout}");
    assert!(!stderr.contains("panicked"), "ember panicked; {ctx}");
    assert_eq!(out.status.code(), Some(2), "exit status; {ctx}");
    let lines: Vec<&str> = stderr.lines().filter(|l| !l.trim().is_empty()).collect();
    assert_eq!(lines.len(), 1, "stderr must be exactly one line; {ctx}");
    let line = lines[0];
    assert!(line.starts_with("error: "), "not an error line; {ctx}");
    assert!(
        line.contains(file),
        "error does not name the file {file:?}; {ctx}"
    );
    for p in phrases {
        assert!(line.contains(p), "error lacks {p:?}; {ctx}");
    }
    let left = dir.outputs();
    assert!(left.is_empty(), "output left behind: {left:?}; {ctx}");
    println!("CASE {case}: {line}");
}

/// A scene-file case: the TOML is `toml`, the mesh is the valid quad.
#[track_caller]
fn toml_case(case: &str, toml: &str, phrases: &[&str]) {
    let (dir, scene) = scene_dir(case, toml, QUAD_OBJ, QUAD_MTL);
    let out = render(&scene, &[]);
    assert_bad_input(case, &out, &dir, "scene.toml", phrases);
}

/// A mesh case: the TOML is valid, the OBJ and MTL are given.
#[track_caller]
fn mesh_case(case: &str, obj: &str, mtl: &str, file: &str, phrases: &[&str]) {
    let (dir, scene) = scene_dir(case, SCENE_TOML, obj, mtl);
    let out = render(&scene, &[]);
    assert_bad_input(case, &out, &dir, file, phrases);
}

/// A mesh case whose whole error line is checked: `expected` is the line after `error: `,
/// with `<dir>` standing for the case directory.
#[track_caller]
fn mesh_case_exact(case: &str, obj: &str, mtl: &str, files: &[(&str, &[u8])], expected: &str) {
    let (dir, scene) = scene_dir(case, SCENE_TOML, obj, mtl);
    for (name, bytes) in files {
        std::fs::write(dir.path().join(name), bytes).expect("cannot write test input");
    }
    let out = render(&scene, &[]);
    let expected = expected.replace("<dir>", &dir.path().display().to_string());
    let file = expected.split(": ").next().expect("a file name");
    assert_bad_input(case, &out, &dir, file, &[]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(stderr.trim(), format!("error: {expected}"), "case {case}");
}

/// `toml` without the table `[name]` (its header and keys).
fn without_table(toml: &str, name: &str) -> String {
    let header = format!("[{name}]");
    assert!(toml.contains(&header), "{header} not in test input");
    let mut out = String::new();
    let mut skipping = false;
    for line in toml.lines() {
        if line.starts_with('[') {
            skipping = line.trim() == header;
        }
        if !skipping {
            out.push_str(line);
            out.push('\n');
        }
    }
    out
}

// ---- positive control ----------------------------------------------------------------------

#[test]
fn valid_scene_renders_exr_and_png() {
    let (dir, scene) = scene_dir("valid", SCENE_TOML, QUAD_OBJ, QUAD_MTL);
    let out = render(&scene, &["--spp", "2", "--threads", "2"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(out.status.success(), "exit {:?}: {stderr}", out.status);
    assert!(!stderr.contains("error"), "{stderr}");
    let exr = dir.path().join("scene.exr");
    let png = dir.path().join("scene.png");
    assert_eq!(dir.outputs(), vec![exr.clone(), png.clone()], "{stderr}");
    let image = ember_cli::image::read_exr(&exr).expect("EXR readable");
    assert_eq!((image.width, image.height), (8, 8));
    assert_eq!(image.non_finite_count(), 0);
    // The quad (radiance 1) covers the middle of the view; the corners see black.
    let mean = image.mean();
    assert!(
        mean.min_element() > 0.3 && mean.max_element() <= 1.0,
        "mean {mean}"
    );
    assert!(std::fs::metadata(&png).expect("PNG").len() > 0);
}

// ---- the scene file ------------------------------------------------------------------------

#[test]
fn scene_file_missing() {
    let dir = TempDir::new("scene-missing");
    let out = render(&dir.path().join("nothere.toml"), &[]);
    assert_bad_input(
        "scene file does not exist",
        &out,
        &dir,
        "nothere.toml",
        &["cannot read scene file", "No such file"],
    );
}

#[test]
fn scene_file_unreadable() {
    // A directory where the scene file should be: unreadable for every user.
    let dir = TempDir::new("scene-is-dir");
    let scene = dir.path().join("scene.toml");
    std::fs::create_dir(&scene).expect("mkdir");
    let out = render(&scene, &[]);
    assert_bad_input(
        "scene file is a directory",
        &out,
        &dir,
        "scene.toml",
        &["cannot read scene file", "Is a directory"],
    );

    // A file without read permission: only a user without CAP_DAC_OVERRIDE is refused (root
    // reads it anyway, so then only the directory case above is checked).
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let (dir, scene) = scene_dir("scene-no-permission", SCENE_TOML, QUAD_OBJ, QUAD_MTL);
        std::fs::set_permissions(&scene, std::fs::Permissions::from_mode(0o000)).expect("chmod");
        if std::fs::File::open(&scene).is_err() {
            let out = render(&scene, &[]);
            assert_bad_input(
                "scene file without read permission",
                &out,
                &dir,
                "scene.toml",
                &["cannot read scene file", "Permission denied"],
            );
        } else {
            println!(
                "CASE scene file without read permission: not checked (this user reads any file)"
            );
        }
        std::fs::set_permissions(&scene, std::fs::Permissions::from_mode(0o644)).expect("chmod");
    }
}

#[test]
fn scene_file_not_utf8() {
    let dir = TempDir::new("scene-not-utf8");
    let scene = dir.path().join("scene.toml");
    let mut bytes = SCENE_TOML.as_bytes().to_vec();
    // Line 2 is `objfile = "quad.obj"`: put a Latin-1 'é' inside the string.
    let at = SCENE_TOML.find("quad.obj").expect("objfile") + 4;
    bytes.insert(at, 0xE9);
    std::fs::write(&scene, bytes).expect("write");
    dir.write("quad.obj", QUAD_OBJ);
    dir.write("quad.mtl", QUAD_MTL);
    let out = render(&scene, &[]);
    assert_bad_input(
        "scene file is not UTF-8",
        &out,
        &dir,
        "scene.toml",
        &["not UTF-8 text", "line 2, column 16"],
    );
}

#[test]
fn toml_syntax_error_gives_line() {
    let toml = edit(
        SCENE_TOML,
        "objfile = \"quad.obj\"\n",
        "objfile = \"quad.obj\"\nthis is not toml\n",
    );
    toml_case("TOML syntax error", &toml, &["TOML syntax error", "line 3"]);
}

#[test]
fn missing_table_film() {
    toml_case(
        "missing [film]",
        &without_table(SCENE_TOML, "film"),
        &["missing table [film]"],
    );
}

#[test]
fn missing_table_renderer() {
    toml_case(
        "missing [renderer]",
        &without_table(SCENE_TOML, "renderer"),
        &["missing table [renderer]"],
    );
}

#[test]
fn missing_table_camera() {
    toml_case(
        "missing [camera]",
        &without_table(SCENE_TOML, "camera"),
        &["missing table [camera]"],
    );
}

#[test]
fn missing_table_input() {
    toml_case(
        "missing [input]",
        &without_table(SCENE_TOML, "input"),
        &["missing table [input]"],
    );
}

#[test]
fn missing_objfile() {
    let toml = edit(SCENE_TOML, "objfile = \"quad.obj\"\n", "");
    toml_case(
        "missing [input].objfile",
        &toml,
        &["missing key [input].objfile"],
    );
}

// ---- wrong types ---------------------------------------------------------------------------

#[test]
fn max_depth_float() {
    let toml = edit(SCENE_TOML, "maxDepth = -1", "maxDepth = 4.0");
    toml_case(
        "maxDepth = 4.0",
        &toml,
        &["[renderer].maxDepth", "must be an integer", "found a float"],
    );
}

#[test]
fn spp_string() {
    let toml = edit(SCENE_TOML, "spp = 2", "spp = \"8\"");
    toml_case(
        "spp = \"8\"",
        &toml,
        &["[renderer].spp", "must be an integer", "found a string"],
    );
}

#[test]
fn is_explicit_integer() {
    let toml = edit(SCENE_TOML, "isExplicit = true", "isExplicit = 1");
    toml_case(
        "isExplicit = 1",
        &toml,
        &[
            "[renderer].isExplicit",
            "must be a boolean",
            "found an integer",
        ],
    );
}

#[test]
fn fov_string() {
    let toml = edit(SCENE_TOML, "fov = 40.0", "fov = \"wide\"");
    toml_case(
        "fov = \"wide\"",
        &toml,
        &["[camera].fov", "must be a number", "found a string"],
    );
}

#[test]
fn eye_two_components() {
    let toml = edit(SCENE_TOML, "eye = [0.0, 0.0, 3.0]", "eye = [0, 1]");
    toml_case(
        "eye = [0, 1]",
        &toml,
        &["[camera].eye", "must have 3 numbers", "found 2"],
    );
}

// ---- renderer type -------------------------------------------------------------------------

#[test]
fn renderer_type_unknown() {
    let toml = edit(SCENE_TOML, "type = \"path\"", "type = \"banana\"");
    toml_case(
        "type = \"banana\"",
        &toml,
        &["\"banana\"", "is not a renderer type"],
    );
}

#[test]
fn bdpt_heuristic_unknown() {
    let toml = edit(
        SCENE_TOML,
        "type = \"path\"",
        "type = \"bdpt\"\nmisHeuristic = \"fast\"",
    );
    toml_case(
        "misHeuristic = \"fast\"",
        &toml,
        &[
            "[renderer].misHeuristic = \"fast\" is not a heuristic",
            "\"power\" and \"balance\"",
        ],
    );
}

#[test]
fn bdpt_depth_beyond_its_cap() {
    let toml = edit(SCENE_TOML, "type = \"path\"", "type = \"bdpt\"");
    let toml = if toml.contains("maxDepth") {
        toml.lines()
            .map(|l| {
                if l.trim_start().starts_with("maxDepth") {
                    "maxDepth = 100"
                } else {
                    l
                }
            })
            .collect::<Vec<_>>()
            .join("\n")
    } else {
        toml.replace("type = \"bdpt\"", "type = \"bdpt\"\nmaxDepth = 100")
    };
    toml_case(
        "maxDepth = 100 with bdpt",
        &toml,
        &[
            "[renderer].maxDepth",
            "maxDepth = 100 is deeper than bidirectional path tracing supports (64",
        ],
    );
}

#[test]
fn renderer_type_not_implemented() {
    let toml = edit(SCENE_TOML, "type = \"path\"", "type = \"ao\"");
    toml_case(
        "type = \"ao\"",
        &toml,
        &["\"ao\"", "ember does not implement"],
    );
}

// ---- out-of-range values -------------------------------------------------------------------

#[test]
fn spp_negative() {
    let toml = edit(SCENE_TOML, "spp = 2", "spp = -4");
    toml_case(
        "spp = -4",
        &toml,
        &["[renderer].spp = -4", "must be a positive integer"],
    );
}

#[test]
fn spp_zero() {
    let toml = edit(SCENE_TOML, "spp = 2", "spp = 0");
    toml_case(
        "spp = 0",
        &toml,
        &["[renderer].spp = 0", "must be a positive integer"],
    );
}

#[test]
fn max_depth_below_minus_one() {
    let toml = edit(SCENE_TOML, "maxDepth = -1", "maxDepth = -2");
    toml_case(
        "maxDepth = -2",
        &toml,
        &["[renderer].maxDepth = -2", "must be -1"],
    );
}

#[test]
fn rr_prob_above_one() {
    let toml = edit(SCENE_TOML, "rrProb = 0.95", "rrProb = 1.5");
    toml_case(
        "rrProb = 1.5",
        &toml,
        &["[renderer].rrProb = 1.5", "must be a probability"],
    );
}

#[test]
fn width_zero() {
    let toml = edit(SCENE_TOML, "width = 8", "width = 0");
    toml_case("width = 0", &toml, &["[film].width = 0", "out of range"]);
}

#[test]
fn width_absurd() {
    let toml = edit(SCENE_TOML, "width = 8", "width = 10000000");
    toml_case(
        "width = 10000000",
        &toml,
        &["[film].width = 10000000", "out of range"],
    );
}

#[test]
fn samples_absurd() {
    // Each side is within range; the product of width, height and spp is not.
    let toml = edit(SCENE_TOML, "width = 8", "width = 32768");
    let toml = edit(&toml, "height = 8", "height = 32768");
    let toml = edit(&toml, "spp = 2", "spp = 10000");
    toml_case(
        "32768 x 32768 pixels at 10000 spp",
        &toml,
        &[
            "32768x32768 pixels x 10000 spp = 10737418240000 samples",
            "more than the limit of 10000000000000",
        ],
    );
}

#[test]
fn image_memory_absurd() {
    // 2^30 pixels at 2 spp: few samples, but image buffers beyond --max-memory-gib (16).
    let toml = edit(SCENE_TOML, "width = 8", "width = 32768");
    let toml = edit(&toml, "height = 8", "height = 32768");
    toml_case(
        "32768 x 32768 film",
        &toml,
        &[
            "a 32768x32768 render needs",
            "GiB of image buffers, more than --max-memory-gib 16",
        ],
    );
}

// ---- command line --------------------------------------------------------------------------

#[test]
fn cli_spp_zero() {
    let (dir, scene) = scene_dir("cli-spp-zero", SCENE_TOML, QUAD_OBJ, QUAD_MTL);
    let out = render(&scene, &["--spp", "0"]);
    assert_bad_input("--spp 0", &out, &dir, "scene.toml", &["--spp"]);
}

#[test]
fn cli_width_absurd() {
    let (dir, scene) = scene_dir("cli-width-absurd", SCENE_TOML, QUAD_OBJ, QUAD_MTL);
    let out = render(&scene, &["--width", "10000000", "--height", "10000000"]);
    assert_bad_input(
        "--width 10000000 --height 10000000",
        &out,
        &dir,
        "scene.toml",
        &["--width", "out of range"],
    );
}

// ---- OBJ and MTL ---------------------------------------------------------------------------

#[test]
fn obj_missing() {
    let toml = edit(
        SCENE_TOML,
        "objfile = \"quad.obj\"",
        "objfile = \"missing.obj\"",
    );
    let (dir, scene) = scene_dir("obj-missing", &toml, QUAD_OBJ, QUAD_MTL);
    let out = render(&scene, &[]);
    assert_bad_input(
        "objfile points to a missing file",
        &out,
        &dir,
        "missing.obj",
        &["not found"],
    );
}

#[test]
fn obj_unreadable() {
    let toml = edit(SCENE_TOML, "objfile = \"quad.obj\"", "objfile = \"meshes\"");
    let (dir, scene) = scene_dir("obj-is-dir", &toml, QUAD_OBJ, QUAD_MTL);
    std::fs::create_dir(dir.path().join("meshes")).expect("mkdir");
    let out = render(&scene, &[]);
    assert_bad_input(
        "objfile is a directory",
        &out,
        &dir,
        "meshes",
        &["cannot read OBJ", "Is a directory"],
    );
}

#[test]
fn obj_faces_without_normals() {
    let obj = edit(QUAD_OBJ, "vn 0 0 1\n", "");
    let obj = edit(&obj, "f 1//1 2//1 3//1 4//1", "f 1 2 3 4");
    mesh_case(
        "OBJ faces without normals",
        &obj,
        QUAD_MTL,
        "quad.obj",
        &["without vertex normals"],
    );
}

#[test]
fn obj_without_faces() {
    let obj = edit(QUAD_OBJ, "f 1//1 2//1 3//1 4//1\n", "");
    mesh_case(
        "OBJ with no faces",
        &obj,
        QUAD_MTL,
        "quad.obj",
        &["has no faces"],
    );
}

#[test]
fn obj_face_index_out_of_range() {
    let obj = edit(QUAD_OBJ, "f 1//1 2//1 3//1 4//1", "f 1//1 2//1 9//1");
    mesh_case(
        "OBJ face index out of range",
        &obj,
        QUAD_MTL,
        "quad.obj",
        &["out of"],
    );
}

#[test]
fn obj_nan_coordinate() {
    let obj = edit(QUAD_OBJ, "v -1 -1 0", "v nan -1 0");
    mesh_case(
        "OBJ with a NaN coordinate",
        &obj,
        QUAD_MTL,
        "quad.obj",
        &["non-finite"],
    );
}

#[test]
fn obj_inf_coordinate() {
    // 1e39 is beyond f32 and parses as +inf, like `inf` itself.
    for (case, v) in [("1e39", "v 1e39 -1 0"), ("inf", "v -1 inf 0")] {
        let obj = edit(QUAD_OBJ, "v -1 -1 0", v);
        let axis = if case == "inf" { "y" } else { "x" };
        mesh_case(
            &format!("OBJ with an {case} coordinate"),
            &obj,
            QUAD_MTL,
            "quad.obj",
            &[
                "line 3:",
                &format!("non-finite {axis} coordinate"),
                &format!("'{v}'"),
            ],
        );
    }
}

#[test]
fn obj_relative_index_before_the_start() {
    // Found by cargo-fuzz: tobj turned this into an unchecked `usize` overflow.
    let obj = edit(QUAD_OBJ, "f 1//1 2//1 3//1 4//1", "f 1//1 2//1 3//-3");
    mesh_case(
        "OBJ face with a relative normal index before the first vn",
        &obj,
        QUAD_MTL,
        "quad.obj",
        &["line 9:", "face index -3", "out of range"],
    );
}

#[test]
fn mtl_unreadable() {
    let (dir, scene) = scene_dir("mtl-is-dir", SCENE_TOML, QUAD_OBJ, QUAD_MTL);
    std::fs::remove_file(dir.path().join("quad.mtl")).expect("rm");
    std::fs::create_dir(dir.path().join("quad.mtl")).expect("mkdir");
    let out = render(&scene, &[]);
    assert_bad_input(
        "mtllib names a directory",
        &out,
        &dir,
        "quad.mtl",
        &["cannot read MTL", "Is a directory", "(mtllib of quad.obj)"],
    );
}

#[test]
fn mtl_missing() {
    let obj = edit(QUAD_OBJ, "mtllib quad.mtl", "mtllib nothere.mtl");
    mesh_case(
        "mtllib names a missing file",
        &obj,
        QUAD_MTL,
        "nothere.mtl",
        &["not found"],
    );
}

#[test]
fn mtl_negative_kd() {
    let mtl = edit(QUAD_MTL, "Kd 0 0 0", "Kd -0.5 0.2 0.2");
    mesh_case(
        "MTL with a negative Kd",
        QUAD_OBJ,
        &mtl,
        "quad.mtl",
        &["material 'light'", "Kd", "non-negative"],
    );
}

#[test]
fn mtl_unknown_illum() {
    let mtl = edit(QUAD_MTL, "illum 7", "illum 42");
    mesh_case(
        "MTL with illum 42",
        QUAD_OBJ,
        &mtl,
        "quad.mtl",
        &[
            "line 4:",
            "material 'light'",
            "illum 42 is not an MTL illumination model (0 to 10",
        ],
    );
}

#[test]
fn mtl_not_a_number() {
    let mtl = edit(QUAD_MTL, "Kd 0 0 0", "Kd 0 red 0");
    mesh_case(
        "MTL with Kd 0 red 0",
        QUAD_OBJ,
        &mtl,
        "quad.mtl",
        &[
            "line 2:",
            "material 'light'",
            "Kd value 'red' is not a number",
        ],
    );
    let mtl = edit(QUAD_MTL, "illum 7", "illum 7.5");
    mesh_case(
        "MTL with illum 7.5",
        QUAD_OBJ,
        &mtl,
        "quad.mtl",
        &["line 4:", "illum value '7.5' is not an integer"],
    );
}

#[test]
fn mtl_colour_with_one_number() {
    // Found by cargo-fuzz: tobj's MTL parser panicked on this (unwrap in parse_float3).
    let mtl = edit(QUAD_MTL, "Kd 0 0 0", "Kd 0.5");
    mesh_case(
        "MTL with Kd 0.5",
        QUAD_OBJ,
        &mtl,
        "quad.mtl",
        &["line 2:", "Kd must have 3 numbers (r g b), found 1"],
    );
}

#[test]
fn mtl_negative_ns() {
    let mtl = edit(QUAD_MTL, "illum 7", "Ns -3\nillum 7");
    mesh_case(
        "MTL with Ns -3",
        QUAD_OBJ,
        &mtl,
        "quad.mtl",
        &[
            "line 4:",
            "material 'light'",
            "Ns = -3 must be finite and >= 0",
        ],
    );
}

#[test]
fn mtl_bad_ior() {
    let mtl = edit(QUAD_MTL, "illum 7", "Ni 0\nillum 6");
    mesh_case_exact(
        "MTL with Ni 0",
        QUAD_OBJ,
        &mtl,
        &[],
        "<dir>/quad.mtl: line 4: material 'light': Ni = 0 must be finite and > 0 (the index of refraction relative to air)",
    );
    let mtl = edit(QUAD_MTL, "illum 7", "Ni 1.5 1.3\nillum 6");
    mesh_case_exact(
        "MTL with two Ni values",
        QUAD_OBJ,
        &mtl,
        &[],
        "<dir>/quad.mtl: line 4: material 'light': Ni must be one number, found '1.5 1.3'",
    );
}

#[test]
fn mtl_bad_roughness() {
    let mtl = edit(QUAD_MTL, "illum 7", "Pr 2\nillum 5");
    mesh_case_exact(
        "MTL with Pr 2",
        QUAD_OBJ,
        &mtl,
        &[],
        "<dir>/quad.mtl: line 4: material 'light': Pr = 2 must be a roughness in [0, 1]",
    );
}

#[test]
fn mtl_bad_transmission_filter() {
    let mtl = edit(QUAD_MTL, "illum 7", "Tf 1 -0.5 1\nillum 6");
    mesh_case_exact(
        "MTL with a negative Tf",
        QUAD_OBJ,
        &mtl,
        &[],
        "<dir>/quad.mtl: line 4: material 'light': Tf = [1, -0.5, 1] must be finite and non-negative",
    );
    let mtl = edit(QUAD_MTL, "illum 7", "Tf spectral glass.rfl 1\nillum 6");
    mesh_case_exact(
        "MTL with Tf spectral",
        QUAD_OBJ,
        &mtl,
        &[],
        "<dir>/quad.mtl: line 4: material 'light': Tf spectral (a spectral curve file) is not supported; give the transmission filter as Tf r g b",
    );
}

#[test]
fn mtl_missing_texture() {
    let mtl = edit(QUAD_MTL, "illum 7", "illum 7\nmap_Kd wood.png");
    mesh_case(
        "MTL map_Kd names a missing file",
        QUAD_OBJ,
        &mtl,
        "quad.mtl",
        &[
            "line 5:",
            "material 'light'",
            "map_Kd texture",
            "wood.png not found",
        ],
    );
}

#[test]
fn mtl_texture_found_renders() {
    // Positive control of the cases above and below: TinyRender loads `<name>.ppm` whatever
    // extension is written, so wood.ppm satisfies map_Kd wood.png.
    let mtl = edit(QUAD_MTL, "illum 7", "illum 7\nmap_Kd wood.png");
    let (dir, scene) = scene_dir("texture-found", SCENE_TOML, UV_QUAD_OBJ, &mtl);
    std::fs::write(dir.path().join("wood.ppm"), b"P6\n1 1\n255\n\x80\x80\x80").expect("write");
    let out = render(&scene, &["--spp", "1"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "exit {:?}: {stderr}", out.status);
    assert!(!stderr.contains("warning"), "{stderr}");
}

/// [`QUAD_OBJ`] with texture coordinates at its corners.
const UV_QUAD_OBJ: &str = "mtllib quad.mtl
o light
v -1 -1 0
v 1 -1 0
v 1 1 0
v -1 1 0
vt 0 0
vt 1 0
vt 1 1
vt 0 1
vn 0 0 1
usemtl light
f 1/1/1 2/2/1 3/3/1 4/4/1
";

/// A texture case: `QUAD_MTL` with `map` on line 5 and the file `name` holding `bytes`.
#[track_caller]
fn texture_case(case: &str, map: &str, name: &str, bytes: &[u8], expected: &str) {
    let mtl = edit(QUAD_MTL, "illum 7", &format!("illum 7\n{map}"));
    mesh_case_exact(case, UV_QUAD_OBJ, &mtl, &[(name, bytes)], expected);
}

#[test]
fn mtl_missing_texture_exact() {
    texture_case(
        "map_Kd names a missing file (exact)",
        "map_Kd wood.png",
        "other.ppm",
        b"",
        "<dir>/quad.mtl: line 5: material 'light': map_Kd texture <dir>/wood.png not found",
    );
}

#[test]
fn texture_truncated() {
    texture_case(
        "truncated PPM",
        "map_Kd wood.ppm",
        "wood.ppm",
        b"P6\n2 2\n255\n\x01\x02\x03",
        "<dir>/quad.mtl: line 5: material 'light': map_Kd texture <dir>/wood.ppm: truncated PPM: expected 12 bytes of pixels, found 3",
    );
}

#[test]
fn texture_not_an_image() {
    texture_case(
        "texture is not an image",
        "map_Kd notes.jpg",
        "notes.jpg",
        b"these are my notes",
        "<dir>/quad.mtl: line 5: material 'light': map_Kd texture <dir>/notes.jpg: not an image (expected binary PPM (P6), PNG or JPEG)",
    );
}

#[test]
fn texture_bad_ppm_header() {
    texture_case(
        "PPM header with a word for the height",
        "map_Kd wood.ppm",
        "wood.ppm",
        b"P6\n2 tall\n255\n",
        "<dir>/quad.mtl: line 5: material 'light': map_Kd texture <dir>/wood.ppm: bad PPM header: the height is not a number (found 't')",
    );
}

#[test]
fn texture_zero_size() {
    texture_case(
        "PPM of width 0",
        "map_Kd wood.ppm",
        "wood.ppm",
        b"P6\n0 2\n255\n",
        "<dir>/quad.mtl: line 5: material 'light': map_Kd texture <dir>/wood.ppm: image size 0x2 is empty",
    );
}

#[test]
fn texture_absurd_size() {
    texture_case(
        "PPM of 100000 x 100000",
        "map_Kd wood.ppm",
        "wood.ppm",
        b"P6\n100000 100000\n255\n",
        "<dir>/quad.mtl: line 5: material 'light': map_Kd texture <dir>/wood.ppm: image size 100000x100000 is larger than 16384x16384",
    );
}

#[test]
fn texture_bad_map_option() {
    texture_case(
        "map option -clamp with a bad value",
        "map_Kd -clamp maybe wood.ppm",
        "wood.ppm",
        b"P6\n1 1\n255\n\0\0\0",
        "<dir>/quad.mtl: line 5: material 'light': map_Kd option -clamp must be on or off, found 'maybe'",
    );
}

#[test]
fn textured_object_without_texture_coordinates() {
    let mtl = edit(QUAD_MTL, "illum 7", "illum 7\nmap_Kd wood.ppm");
    mesh_case_exact(
        "textured material on an object without vt",
        QUAD_OBJ,
        &mtl,
        &[("wood.ppm", b"P6\n1 1\n255\n\0\0\0")],
        "<dir>/quad.obj: object 'light' uses the textured material 'light' but has faces without texture coordinates (write faces as f v/vt/vn)",
    );
}

// ---- output --------------------------------------------------------------------------------

#[test]
fn output_directory_missing() {
    let (dir, scene) = scene_dir("out-dir-missing", SCENE_TOML, QUAD_OBJ, QUAD_MTL);
    let missing = dir.path().join("no-such-dir");
    let target = missing.join("x.exr");
    let out = render(&scene, &["-o", target.to_str().expect("UTF-8 path")]);
    assert_bad_input(
        "-o into a missing directory",
        &out,
        &dir,
        "x.exr",
        &["directory", "does not exist"],
    );
    assert!(!missing.exists(), "ember created the output directory");
}

#[test]
fn output_directory_missing_absolute() {
    let missing = Path::new("/nonexistent-dir");
    assert!(!missing.exists(), "/nonexistent-dir exists on this machine");
    let (dir, scene) = scene_dir("out-dir-missing-abs", SCENE_TOML, QUAD_OBJ, QUAD_MTL);
    let out = render(&scene, &["-o", "/nonexistent-dir/x.exr"]);
    assert_bad_input(
        "-o /nonexistent-dir/x.exr",
        &out,
        &dir,
        "/nonexistent-dir/x.exr",
        &["directory", "does not exist"],
    );
    assert!(!missing.exists(), "ember created the output directory");
}

#[test]
fn png_preview_unwritable_leaves_no_exr() {
    // The EXR can be written but the PNG cannot (a directory is in its way): the run fails and
    // the EXR it had just written is removed, so no half of the output is left.
    let (dir, scene) = scene_dir("png-blocked", SCENE_TOML, QUAD_OBJ, QUAD_MTL);
    std::fs::create_dir(dir.path().join("scene.png")).expect("mkdir");
    let out = render(&scene, &[]);
    assert_bad_input(
        "PNG preview path is a directory",
        &out,
        &dir,
        "scene.png",
        &["cannot"],
    );
}

#[test]
fn output_named_png() {
    // `-o x.png` would write the EXR to x.png and then overwrite it with the preview.
    let (dir, scene) = scene_dir("out-png", SCENE_TOML, QUAD_OBJ, QUAD_MTL);
    let target = dir.path().join("x.png");
    let out = render(&scene, &["-o", target.to_str().expect("UTF-8 path")]);
    assert_bad_input("-o x.png", &out, &dir, "x.png", &["png"]);
}
