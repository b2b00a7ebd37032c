//! The `afs` command line: outputs, dumps, and bad input giving a clear
//! error and a non-zero exit code, never a panic.

use std::path::Path;
use std::process::{Command, Output};

fn afs(args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_afs"))
        .args(args)
        .current_dir(dir)
        .env("XDG_RUNTIME_DIR", "/tmp")
        // The validation layer is on: a message makes `afs` fail.
        .env("AFS_VALIDATION", "1")
        .output()
        .expect("run afs")
}

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// Runs `afs` expecting failure: exit code 1 (not a panic's 101), and an
/// error line containing every needle.
fn expect_error(args: &[&str], dir: &Path, needles: &[&str]) {
    let o = afs(args, dir);
    let t = text(&o);
    assert_eq!(
        o.status.code(),
        Some(1),
        "afs {args:?} should fail cleanly:\n{t}"
    );
    assert!(!t.contains("panicked"), "afs {args:?} panicked:\n{t}");
    assert!(t.contains("error:"), "afs {args:?}: no error line:\n{t}");
    for n in needles {
        assert!(
            t.contains(n),
            "afs {args:?}: error should mention {n:?}:\n{t}"
        );
    }
}

fn write(dir: &Path, name: &str, data: impl AsRef<[u8]>) -> String {
    let p = dir.join(name);
    std::fs::write(&p, data).unwrap();
    p.to_str().unwrap().to_string()
}

/// A one-triangle glTF whose buffer is the given 36 bytes (3 f32 vec3).
fn triangle_gltf(uri: &str) -> String {
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],
"meshes":[{{"name":"tri","primitives":[{{"attributes":{{"POSITION":0}}}}]}}],
"accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}}],
"bufferViews":[{{"buffer":0,"byteLength":36}}],"buffers":[{{"byteLength":36,"uri":"{uri}"}}]}}"#
    )
}

fn f32_bytes(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

#[test]
fn render_writes_image_and_dump_and_compare_reads_it() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let o = afs(
        &[
            "render",
            "builtin:plane_sphere",
            "--width",
            "48",
            "--height",
            "32",
            "-o",
            "a.png",
            "--dump",
            "dump_a",
            "--quiet",
        ],
        d,
    );
    assert!(o.status.success(), "{}", text(&o));
    let img = image::open(d.join("a.png")).unwrap();
    assert_eq!((img.width(), img.height()), (48, 32));
    for f in [
        "position.exr",
        "normal.exr",
        "visibility_0.exr",
        "scene.json",
        "stats.json",
        "image.png",
    ] {
        assert!(d.join("dump_a").join(f).is_file(), "dump lacks {f}");
    }
    // Nothing left under a temporary name.
    let partial = std::fs::read_dir(d.join("dump_a"))
        .unwrap()
        .filter(|e| {
            e.as_ref()
                .unwrap()
                .file_name()
                .to_string_lossy()
                .starts_with(".partial")
        })
        .count();
    assert_eq!(partial, 0);

    let o = afs(&["compare", "dump_a", "dump_a", "--json"], d);
    assert!(o.status.success(), "{}", text(&o));
    let rows: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(rows[0]["max_abs"].as_f64(), Some(0.0));
    assert!(rows[0]["pixels"].as_u64().unwrap() > 0);
}

#[test]
fn help_explains_itself() {
    let o = afs(&["--help"], Path::new("."));
    let t = text(&o);
    assert!(o.status.success());
    for w in ["render", "reference", "compare", "info", "builtin:"] {
        assert!(t.contains(w), "--help lacks {w}:\n{t}");
    }
    let o = afs(&["render", "--help"], Path::new("."));
    let t = text(&o);
    for w in [
        "--dump",
        "--stats",
        "--light-texels",
        "--device",
        "--samples",
    ] {
        assert!(t.contains(w), "render --help lacks {w}:\n{t}");
    }
}

#[test]
fn bad_scene_files_fail_with_named_errors() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let unknown = write(
        d,
        "unknown.toml",
        "scene = \"builtin:plane_sphere\"\nlights = 3\n",
    );
    expect_error(
        &["render", &unknown, "--quiet"],
        d,
        &["unknown.toml", "lights"],
    );
    let wrong = write(
        d,
        "wrong.toml",
        "scene = \"builtin:plane_sphere\"\n[camera]\neye = \"up\"\ntarget = [0.0, 0.0, 0.0]\n",
    );
    expect_error(&["render", &wrong, "--quiet"], d, &["wrong.toml", "eye"]);
    let malformed = write(d, "malformed.toml", "scene = [\n");
    expect_error(&["render", &malformed, "--quiet"], d, &["malformed.toml"]);
    expect_error(&["render", "builtin:nonsense", "--quiet"], d, &["nonsense"]);
    expect_error(&["render", "missing.glb", "--quiet"], d, &["missing.glb"]);
    expect_error(
        &["render", "builtin:plane_sphere", "--width", "0", "--quiet"],
        d,
        &["size"],
    );
    expect_error(
        &["render", "builtin:demo", "--samples", "0", "--quiet"],
        d,
        &["samples"],
    );
    expect_error(
        &["render", "builtin:demo", "--samples", "5000", "--quiet"],
        d,
        &["samples"],
    );
}

#[test]
fn bad_gltf_fails_with_named_errors() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // Missing .bin
    let missing = write(d, "missing_bin.gltf", triangle_gltf("nowhere.bin"));
    expect_error(
        &["render", &missing, "--quiet"],
        d,
        &["missing_bin.gltf", "tri"],
    );
    // NaN vertex
    write(
        d,
        "nan.bin",
        f32_bytes(&[0.0, 0.0, 0.0, 1.0, f32::NAN, 0.0, 0.0, 1.0, 0.0]),
    );
    let nan = write(d, "nan.gltf", triangle_gltf("nan.bin"));
    expect_error(&["render", &nan, "--quiet"], d, &["nan.gltf", "tri"]);
    // Empty scene
    let empty = write(
        d,
        "empty.gltf",
        r#"{"asset":{"version":"2.0"},"scenes":[{"nodes":[]}],"scene":0}"#,
    );
    expect_error(
        &["render", &empty, "--quiet"],
        d,
        &["empty.gltf", "no triangles"],
    );
    // Truncated .glb: a valid one cut short.
    let o = afs(&["export", "builtin:plane_sphere", "-o", "ok.glb"], d);
    assert!(o.status.success(), "{}", text(&o));
    let bytes = std::fs::read(d.join("ok.glb")).unwrap();
    for cut in [10, 100, bytes.len() / 2, bytes.len() - 1] {
        let name = format!("cut{cut}.glb");
        let p = write(d, &name, &bytes[..cut]);
        expect_error(&["render", &p, "--quiet"], d, &[&name]);
    }
    // A valid file still renders (the test above would pass for a loader that rejects everything).
    let ok = d.join("ok.glb");
    let o = afs(
        &[
            "render",
            ok.to_str().unwrap(),
            "--width",
            "16",
            "--height",
            "16",
            "--quiet",
        ],
        d,
    );
    assert!(o.status.success(), "{}", text(&o));
}

#[test]
fn info_lists_lavapipe_limits() {
    let o = afs(&["info"], Path::new("."));
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    if t.contains("llvmpipe") {
        assert!(t.contains("maxStorageBufferRange"), "{t}");
        assert!(t.contains("134217728"), "{t}");
    } else {
        panic!("lavapipe (llvmpipe) not listed; install mesa-vulkan-drivers:\n{t}");
    }
}
