//! The CI half of the loader fuzzing (README.md, "Fuzzing"). cargo-fuzz needs nightly and
//! hours; here a proptest byte-mutation harness runs the committed corpus
//! (`tests/fuzz-corpus/{scene_toml,obj,obj_mtl}/`, minimised from the cargo-fuzz runs) and
//! mutations of it through the same entry points as the fuzz targets
//! (`ember_cli::fuzzing`), for about ten seconds in release.
//!
//! Every input must return normally, `Loaded` or `Refused`, within [`TIME_LIMIT`]; a refusal
//! must name the file and be one line (checked in `ember_cli::fuzzing`, which panics when the
//! contract is broken). About 500 000 inputs, 15 s of CPU in release (a fiftieth in a debug
//! build). The runs are deterministic; `EMBER_FUZZ_SEED=<u64>` picks another
//! sequence and `EMBER_FUZZ_CASES=<n>` scales the number of mutated inputs, to fuzz longer by
//! hand.

use ember_cli::fuzzing::{self, Outcome, CORNELL_MTL};
use proptest::prelude::*;
use proptest::sample::Index;
use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Longest any single input may take. The slowest corpus input takes about a millisecond in
/// release; this only catches a hang or a blow-up (a debug build is 10-30x slower).
const TIME_LIMIT: Duration = Duration::from_secs(2);

fn corpus_dir(target: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fuzz-corpus")
        .join(target)
}

/// The committed corpus of one target, sorted by file name.
fn corpus(target: &str) -> Vec<(String, Vec<u8>)> {
    let dir = corpus_dir(target);
    let mut files: Vec<(String, Vec<u8>)> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| {
            let path = e.expect("directory entry").path();
            let name = path
                .file_name()
                .expect("name")
                .to_string_lossy()
                .into_owned();
            let bytes = std::fs::read(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
            (name, bytes)
        })
        .collect();
    files.sort();
    assert!(
        files.len() >= 10,
        "{}: only {} corpus files",
        dir.display(),
        files.len()
    );
    files
}

/// The fuzz target `target` on one input, timed.
fn run(target: &str, input: &[u8]) -> Outcome {
    let start = Instant::now();
    let outcome = match target {
        "scene_toml" => fuzzing::scene_toml(input),
        "obj" => fuzzing::obj(input, CORNELL_MTL),
        "obj_mtl" => {
            let (obj, mtl) = fuzzing::split_obj_mtl(input);
            fuzzing::obj(obj, mtl)
        }
        _ => unreachable!("no target {target}"),
    };
    let took = start.elapsed();
    assert!(
        took < TIME_LIMIT,
        "{target}: an input of {} bytes took {took:?}: {:?}",
        input.len(),
        String::from_utf8_lossy(&input[..input.len().min(300)])
    );
    outcome
}

/// Runs every committed input; the corpus holds both scenes that load and inputs that are
/// refused (so a loader that refuses everything, or accepts everything, fails here too).
fn replay(target: &str) {
    /// Names the input when a loader panics (the panic itself fails the test).
    struct Context(String);
    impl Drop for Context {
        fn drop(&mut self) {
            if std::thread::panicking() {
                eprintln!("while running corpus file {}", self.0);
            }
        }
    }
    let mut counts = [0usize; 2];
    for (name, bytes) in corpus(target) {
        let context = Context(format!("{target}/{name}"));
        let outcome = run(target, &bytes);
        drop(context);
        counts[usize::from(outcome == Outcome::Refused)] += 1;
    }
    println!("{target}: {} loaded, {} refused", counts[0], counts[1]);
    assert!(counts[0] > 0 && counts[1] > 0, "{target}: {counts:?}");
}

#[test]
fn replay_corpus_scene_toml() {
    replay("scene_toml");
}

#[test]
fn replay_corpus_obj() {
    replay("obj");
}

#[test]
fn replay_corpus_obj_mtl() {
    replay("obj_mtl");
}

// ---- crashes found by cargo-fuzz ------------------------------------------------------------

/// `OBJ \0 MTL` of a corpus regression file.
fn regression(target: &str, name: &str) -> Vec<u8> {
    let path = corpus_dir(target).join(name);
    std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The error the OBJ loader gives for a regression input of the `obj_mtl` corpus.
fn obj_error(name: &str) -> String {
    let input = regression("obj_mtl", name);
    let (obj, mtl) = fuzzing::split_obj_mtl(&input);
    let files = |p: &Path| (p.extension()? == "mtl").then(|| mtl.to_vec());
    match ember_cli::mesh::SceneData::parse_obj(Path::new(fuzzing::OBJ_PATH), obj, &files) {
        Ok(_) => panic!("{name}: loaded"),
        Err(e) => e.to_string(),
    }
}

/// tobj 4.0.5 unwraps the parse of an MTL colour (`parse_float3`), so `Kd 1` (one number)
/// panicked in every build of `ember`. MTL files are now parsed by ember.
#[test]
fn regression_mtl_colour_with_one_number() {
    assert_eq!(
        obj_error("crash-tobj-mtl-colour-one-number"),
        "fuzz/quad.mtl: line 2: material 'light': Kd must have 3 numbers (r g b), found 1"
    );
}

/// tobj resolves a relative index before the first vertex to a huge `usize` and computes
/// `vn * 3` unchecked: an overflow panic with debug assertions, a wrapped index in release.
#[test]
fn regression_relative_normal_index_before_the_start() {
    assert_eq!(
        obj_error("crash-tobj-relative-normal-overflow"),
        "fuzz/mesh.obj: line 5: face index -3 in '3//-3' is out of range: the vn lines before it are -1..=-1"
    );
}

/// The same overflow for texture coordinates (`vt * 2`).
#[test]
fn regression_relative_texcoord_index_before_the_start() {
    assert_eq!(
        obj_error("crash-tobj-relative-texcoord-overflow"),
        "fuzz/mesh.obj: line 6: face index -3 in '3/-3/1' is out of range: the vt lines before it are -1..=-1"
    );
}

/// Found by this harness (the word `1e-45` substituted into `fov`): a field of view too small
/// for f32 gave a camera with tan(fov/2) = 0, every ray in the same direction.
#[test]
fn regression_fov_underflow() {
    let input = regression("scene_toml", "regression-fov-underflow.toml");
    assert_eq!(run("scene_toml", &input), Outcome::Refused);
    let e = ember_cli::scene_file::SceneFile::parse_bytes(Path::new("scene.toml"), &input)
        .expect_err("fov = 1e-40 accepted");
    assert_eq!(
        e.to_string(),
        "scene.toml: [camera].fov = 1e-40 degrees is too small for f32 (the view would be a point)"
    );
}

/// The textured seed loads with its texture (the harness serves [`fuzzing::TEXTURE_PPM`] for
/// texture names starting with `t`), so mutations reach texture decoding and coordinates.
#[test]
fn textured_seed_loads_with_its_texture() {
    let input = regression("obj_mtl", "seed-textured-quad");
    assert_eq!(run("obj_mtl", &input), Outcome::Loaded);
    let (obj, mtl) = fuzzing::split_obj_mtl(&input);
    let files = |p: &Path| {
        if p.extension()? == "mtl" {
            Some(mtl.to_vec())
        } else {
            p.file_name()?
                .to_string_lossy()
                .starts_with('t')
                .then(|| fuzzing::TEXTURE_PPM.to_vec())
        }
    };
    let scene = ember_cli::mesh::SceneData::parse_obj(Path::new(fuzzing::OBJ_PATH), obj, &files)
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(scene.texels.len(), 4);
    assert_eq!(scene.textures.len(), 2, "tex.ppm with and without -s/-o");
    assert_eq!(scene.uvs.len(), scene.positions.len());
}

// ---- mutations of the corpus ---------------------------------------------------------------

/// Words a mutation inserts or substitutes: numbers at and past the limits of f32, i64 and
/// u64, non-numbers the parsers accept as floats, structure characters and keywords.
const INTERESTING: &[&str] = &[
    "nan",
    "NaN",
    "inf",
    "-inf",
    "infinity",
    "-1",
    "0",
    "-0",
    "1",
    "1e39",
    "-1e39",
    "1e-45",
    "3.4028235e38",
    "2147483648",
    "4294967296",
    "9223372036854775807",
    "-9223372036854775808",
    "18446744073709551615",
    "99999999999999999999999",
    "6148914691236517206",
    "-6148914691236517207",
    "",
    " ",
    "\n",
    "\r\n",
    "\t",
    "/",
    "//",
    "#",
    "=",
    "[",
    "]",
    "{",
    "\"",
    "'''",
    "\\u0000",
    "\0",
    "\u{feff}",
    "é",
    "\u{2028}",
    "v",
    "vn",
    "vt",
    "f",
    "l",
    "o",
    "g",
    "usemtl",
    "mtllib",
    "newmtl",
    "Kd",
    "Ks",
    "Ke",
    "Ns",
    "illum",
    "Ni",
    "Pr",
    "Tf",
    "spectral",
    "map_Kd",
    "map_Ks",
    "-s",
    "-o",
    "-bm",
    "-clamp",
    "-mm",
    "-imfchan",
    "on",
    "tex.ppm",
    "missing.png",
    "[input]",
    "[camera]",
    "[film]",
    "[renderer]",
    "type",
    "realtime",
    "spp",
    "width",
    "maxDepth",
    "\"gi\"",
    "true",
];

#[derive(Clone, Debug)]
enum Mutation {
    FlipBit(Index, u8),
    SetByte(Index, u8),
    Insert(Index, Vec<u8>),
    Delete(Index, usize),
    /// Insert an interesting word, or replace the word at the position with it.
    Word(Index, usize, bool),
    /// Insert a piece of another corpus file.
    Splice(Index, Index, Index, usize),
    /// Repeat the line at the position (up to thousands of times: hangs and blow-ups).
    RepeatLine(Index, usize),
}

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        2 => (any::<Index>(), 0u8..8).prop_map(|(i, b)| Mutation::FlipBit(i, b)),
        2 => (any::<Index>(), any::<u8>()).prop_map(|(i, b)| Mutation::SetByte(i, b)),
        2 => (any::<Index>(), prop::collection::vec(any::<u8>(), 1..8))
            .prop_map(|(i, b)| Mutation::Insert(i, b)),
        2 => (any::<Index>(), 1usize..32).prop_map(|(i, n)| Mutation::Delete(i, n)),
        6 => (any::<Index>(), 0..INTERESTING.len(), any::<bool>())
            .prop_map(|(i, w, r)| Mutation::Word(i, w, r)),
        2 => (any::<Index>(), any::<Index>(), any::<Index>(), 1usize..200)
            .prop_map(|(a, f, b, n)| Mutation::Splice(a, f, b, n)),
        1 => (any::<Index>(), prop_oneof![1usize..10, 100usize..3000])
            .prop_map(|(i, n)| Mutation::RepeatLine(i, n)),
    ]
}

/// A position in `0..=len`.
fn at(i: &Index, len: usize) -> usize {
    i.index(len + 1)
}

fn apply(bytes: &mut Vec<u8>, m: &Mutation, files: &[(String, Vec<u8>)]) {
    let len = bytes.len();
    match m {
        Mutation::FlipBit(i, bit) if len > 0 => bytes[i.index(len)] ^= 1 << bit,
        Mutation::SetByte(i, b) if len > 0 => bytes[i.index(len)] = *b,
        Mutation::FlipBit(..) | Mutation::SetByte(..) => {}
        Mutation::Insert(i, b) => {
            let p = at(i, len);
            bytes.splice(p..p, b.iter().copied());
        }
        Mutation::Delete(i, n) => {
            let p = at(i, len);
            bytes.drain(p..(p + n).min(len));
        }
        Mutation::Word(i, w, replace) => {
            let word = INTERESTING[*w].as_bytes();
            let p = at(i, len);
            let (start, end) = if *replace {
                let is_space = |b: &u8| b.is_ascii_whitespace();
                let start = bytes[..p].iter().rposition(is_space).map_or(0, |s| s + 1);
                let end = bytes[p..].iter().position(is_space).map_or(len, |e| p + e);
                (start, end)
            } else {
                (p, p)
            };
            bytes.splice(start..end, word.iter().copied());
        }
        Mutation::Splice(i, f, from, n) => {
            let other = &files[f.index(files.len())].1;
            let p = at(i, len);
            let s = at(from, other.len());
            bytes.splice(p..p, other[s..(s + n).min(other.len())].iter().copied());
        }
        Mutation::RepeatLine(i, n) => {
            let p = at(i, len);
            let start = bytes[..p]
                .iter()
                .rposition(|&b| b == b'\n')
                .map_or(0, |s| s + 1);
            let end = bytes[p..]
                .iter()
                .position(|&b| b == b'\n')
                .map_or(len, |e| p + e + 1);
            let mut line = bytes[start..end].to_vec();
            if line.last() != Some(&b'\n') {
                line.push(b'\n');
            }
            let repeated = line.repeat(*n);
            bytes.splice(start..start, repeated);
        }
    }
}

fn env_u64(name: &str) -> Option<u64> {
    let v = std::env::var(name).ok()?;
    Some(
        v.parse()
            .unwrap_or_else(|_| panic!("{name}={v:?} is not a number")),
    )
}

/// `cases` mutated corpus inputs of `target` through the target.
fn mutate(target: &str, cases: u32) {
    let files = corpus(target);
    // A debug build is 10-30x slower: it runs a fiftieth (CI runs release).
    let cases = if cfg!(debug_assertions) {
        cases / 50
    } else {
        cases
    };
    let cases = env_u64("EMBER_FUZZ_CASES").map_or(cases, |c| c as u32);
    let rng = match env_u64("EMBER_FUZZ_SEED") {
        Some(seed) => {
            let mut key = [0u8; 32];
            key[..8].copy_from_slice(&seed.to_le_bytes());
            TestRng::from_seed(RngAlgorithm::ChaCha, &key)
        }
        None => TestRng::deterministic_rng(RngAlgorithm::ChaCha),
    };
    let config = Config {
        cases,
        failure_persistence: None,
        max_shrink_iters: 2000,
        ..Config::default()
    };
    let mut runner = TestRunner::new_with_rng(config, rng);
    // Most corpus inputs are refused early; half of the mutations start from one that loads,
    // so that the emitter table, BVH and validation see mutated scenes too.
    let loadable: Vec<usize> = (0..files.len())
        .filter(|&i| run(target, &files[i].1) == Outcome::Loaded)
        .collect();
    let counts = std::cell::Cell::new([0usize; 2]);
    let strategy = (
        any::<bool>(),
        any::<Index>(),
        prop::collection::vec(mutation(), 1..5),
    );
    let start = Instant::now();
    let result = runner.run(&strategy, |(from_loadable, file, mutations)| {
        let file = if from_loadable && !loadable.is_empty() {
            loadable[file.index(loadable.len())]
        } else {
            file.index(files.len())
        };
        let (_, original) = &files[file];
        let mut bytes = original.clone();
        for m in &mutations {
            apply(&mut bytes, m, &files);
        }
        let outcome = run(target, &bytes);
        let mut c = counts.get();
        c[usize::from(outcome == Outcome::Refused)] += 1;
        counts.set(c);
        Ok(())
    });
    if let Err(e) = result {
        panic!("{target}: {e}");
    }
    let c = counts.get();
    println!(
        "{target}: {cases} mutated inputs in {:.1} s: {} loaded, {} refused",
        start.elapsed().as_secs_f64(),
        c[0],
        c[1]
    );
    // Mutations that never break an input, or never leave one intact, test little.
    assert!(c[0] > 0 && c[1] > 0, "{target}: {c:?}");
}

#[test]
fn mutated_scene_toml() {
    mutate("scene_toml", 300_000);
}

#[test]
fn mutated_obj() {
    mutate("obj", 100_000);
}

#[test]
fn mutated_obj_mtl() {
    mutate("obj_mtl", 100_000);
}
