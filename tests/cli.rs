//! The `afs` command line: outputs, dumps, and bad input giving a clear
//! error and a non-zero exit code, never a panic.

use std::io::Read;
use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

/// How long one `afs` run may take before the test calls it a hang.
const DEADLINE: Duration = Duration::from_secs(60);

/// Runs `afs` in `dir`; kills it and fails the test when it runs past
/// [`DEADLINE`].
fn afs(args: &[&str], dir: &Path) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_afs"))
        .args(args)
        .current_dir(dir)
        .env("XDG_RUNTIME_DIR", "/tmp")
        // The validation layer is on: a message makes `afs` fail.
        .env("AFS_VALIDATION", "1")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run afs");
    // Drained on threads so that a full pipe cannot stall the child.
    let drain = |mut r: Box<dyn Read + Send>| {
        std::thread::spawn(move || {
            let mut b = Vec::new();
            let _ = r.read_to_end(&mut b);
            b
        })
    };
    let stdout = drain(Box::new(child.stdout.take().unwrap()));
    let stderr = drain(Box::new(child.stderr.take().unwrap()));
    let start = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().expect("wait for afs") {
            break status;
        }
        if start.elapsed() > DEADLINE {
            let _ = child.kill();
            let _ = child.wait();
            panic!("afs {args:?} still running after {DEADLINE:?}: killed (a hang?)");
        }
        std::thread::sleep(Duration::from_millis(10));
    };
    Output {
        status,
        stdout: stdout.join().unwrap(),
        stderr: stderr.join().unwrap(),
    }
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
    expect_exit(args, dir, 1, needles)
}

/// Runs `afs` expecting a command-line usage error (clap's exit code 2)
/// whose text contains every needle.
fn expect_usage_error(args: &[&str], dir: &Path, needles: &[&str]) {
    expect_exit(args, dir, 2, needles)
}

/// Runs `afs` expecting exit code `code`, an error line, every needle, no
/// panic, and no output left behind: neither the image (`-o`, default
/// `out.png`) nor its temporary `.partial-output.` file.
fn expect_exit(args: &[&str], dir: &Path, code: i32, needles: &[&str]) {
    let o = afs(args, dir);
    let t = text(&o);
    eprintln!("afs {args:?}: {}", t.trim());
    assert_eq!(
        o.status.code(),
        Some(code),
        "afs {args:?} should fail cleanly with exit code {code}:\n{t}"
    );
    assert!(!t.contains("panicked"), "afs {args:?} panicked:\n{t}");
    assert!(t.contains("error:"), "afs {args:?}: no error line:\n{t}");
    for n in needles {
        assert!(
            t.contains(n),
            "afs {args:?}: error should mention {n:?}:\n{t}"
        );
    }
    let output = args
        .iter()
        .position(|a| *a == "-o" || *a == "--output")
        .and_then(|i| args.get(i + 1))
        .copied()
        .unwrap_or("out.png");
    let output = dir.join(output);
    if output.is_dir() {
        return; // a case about `-o` naming a folder
    }
    assert!(
        !output.exists(),
        "afs {args:?} failed but left {}:\n{t}",
        output.display()
    );
    let partial = output.with_file_name(format!(
        ".partial-output.{}",
        output.file_name().unwrap().to_string_lossy()
    ));
    assert!(!partial.exists(), "afs {args:?} left {}", partial.display());
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

/// A one-light dump in `dir` holds every file and nothing under a
/// temporary name.
fn assert_complete_dump(dir: &Path) {
    for f in [
        "position.exr",
        "normal.exr",
        "visibility_0.exr",
        "scene.json",
        "stats.json",
        "image.png",
    ] {
        assert!(dir.join(f).is_file(), "dump lacks {f}");
    }
    let left: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with(".partial"))
        .collect();
    assert!(left.is_empty(), "{left:?}");
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
    assert_complete_dump(&d.join("dump_a"));

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

/// Writes `body` after `scene = "builtin:plane_sphere"` as `name` in `d`.
fn scene_file(d: &Path, name: &str, body: &str) -> String {
    write(
        d,
        name,
        format!("scene = \"builtin:plane_sphere\"\n{body}\n"),
    )
}

#[test]
fn non_finite_and_far_scene_file_values_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let camera = |eye: &str, target: &str, up: &str, fov: &str| {
        format!("[camera]\neye = {eye}\ntarget = {target}\nup = {up}\nfov_y_deg = {fov}\nwidth = 16\nheight = 16")
    };
    let (eye, target, up, fov) = (
        "[0.0, 2.0, 5.0]",
        "[0.0, 0.5, 0.0]",
        "[0.0, 1.0, 0.0]",
        "45.0",
    );
    // X: the bad number; V: a vector holding it. Every field of every
    // light kind that holds a number.
    let lights = [
        ("kind = \"point\"\nposition = V", "position"),
        ("kind = \"point\"\nposition = [0.0, 4.0, 0.0]\nintensity = X", "intensity"),
        ("kind = \"point\"\nposition = [0.0, 4.0, 0.0]\ncolor = [1.0, X, 1.0]", "color"),
        ("kind = \"directional\"\ndirection = V", "direction"),
        ("kind = \"sphere\"\nposition = V\nradius = 0.5", "position"),
        ("kind = \"sphere\"\nposition = [0.0, 4.0, 0.0]\nradius = X", "radius"),
        ("kind = \"disk\"\nposition = V\nradius = 0.5", "position"),
        ("kind = \"disk\"\nposition = [0.0, 4.0, 0.0]\nradius = X", "radius"),
        ("kind = \"disk\"\nposition = [0.0, 4.0, 0.0]\nradius = 0.5\nnormal = V", "normal"),
        ("kind = \"disk\"\nposition = [0.0, 4.0, 0.0]\nradius = 0.5\ntangent = V", "tangent"),
        ("kind = \"rect\"\nposition = V\nsize = [1.0, 0.5]", "position"),
        ("kind = \"rect\"\nposition = [0.0, 4.0, 0.0]\nsize = [X, 0.5]", "size"),
        ("kind = \"rect\"\nposition = [0.0, 4.0, 0.0]\nsize = [1.0, 0.5]\nnormal = V", "normal"),
        ("kind = \"rect\"\nposition = [0.0, 4.0, 0.0]\nsize = [1.0, 0.5]\ntangent = V", "tangent"),
        ("kind = \"ellipsoid\"\nposition = V\nsemi_axes = [0.5, 0.2, 0.3]", "position"),
        ("kind = \"ellipsoid\"\nposition = [0.0, 4.0, 0.0]\nsemi_axes = [0.5, X, 0.3]", "semi_axes"),
        ("kind = \"ellipsoid\"\nposition = [0.0, 4.0, 0.0]\nsemi_axes = [0.5, 0.2, 0.3]\nnormal = V", "normal"),
        ("kind = \"explicit\"\npositions = [[0.0, 4.0, 0.0], V]", "positions"),
        ("kind = \"sphere\"\nposition = [0.0, 4.0, 0.0]\nradius = 0.5\nintensity = X", "intensity"),
    ];
    let mut cases: Vec<(String, &str)> = Vec::new();
    for x in ["nan", "inf", "-inf", "-nan"] {
        let v = format!("[0.0, {x}, 0.0]");
        cases.push((camera(&v, target, up, fov), "eye"));
        cases.push((camera(eye, &v, up, fov), "target"));
        cases.push((camera(eye, target, &v, fov), "up"));
        cases.push((camera(eye, target, up, x), "fov_y_deg"));
        for (light, key) in lights {
            let l = light.replace('V', &v).replace('X', x);
            cases.push((format!("[[light]]\n{l}"), key));
        }
        cases.push((format!("ground = {{ y = {x}, half_size = 1.0 }}"), "ground"));
    }
    // Finite, but too far from the camera for the f32 GPU passes (or, for
    // colour and intensity, past f32). A far target or up vector is only a
    // direction, and directions are normalised: those are fine.
    let x = "1e300";
    let v = "[0.0, 1e300, 0.0]";
    cases.push((camera("[1e300, 2.0, 5.0]", target, up, fov), "eye"));
    cases.push((camera(eye, target, up, x), "fov_y_deg"));
    cases.push((camera(eye, "[1e300, 0.0, 1e300]", up, fov), "target"));
    for (light, key) in lights {
        if matches!(key, "normal" | "tangent" | "direction") {
            continue;
        }
        let l = light.replace('V', v).replace('X', x);
        cases.push((format!("[[light]]\n{l}"), key));
    }
    cases.push(("ground = { y = 0.0, half_size = 1e300 }".into(), "ground"));
    for (i, (body, key)) in cases.iter().enumerate() {
        let name = format!("case{i}.toml");
        let p = scene_file(d, &name, body);
        expect_error(&["render", &p, "--quiet"], d, &[&name, key]);
    }
}

#[test]
fn malformed_and_invalid_scene_files_fail_with_named_errors() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let raw = |name: &str, bytes: &[u8]| write(d, name, bytes);
    let cases: Vec<(String, Vec<&str>)> = vec![
        (raw("binary.toml", b"scene = \"\xff\xfe\x00\x80\"\n"), vec!["binary.toml"]),
        (raw("empty.toml", b""), vec!["empty.toml", "scene"]),
        (raw("twice.toml", b"scene = \"builtin:demo\"\nscene = \"builtin:demo\"\n"), vec!["twice.toml", "scene"]),
        (raw("unclosed.toml", b"scene = \"builtin:demo\"\n[camera\n"), vec!["unclosed.toml"]),
        (scene_file(d, "width.toml", "[camera]\neye = [0.0, 2.0, 5.0]\ntarget = [0.0, 0.0, 0.0]\nwidth = -1"), vec!["width.toml", "width"]),
        (scene_file(d, "huge.toml", "[camera]\neye = [0.0, 2.0, 5.0]\ntarget = [0.0, 0.0, 0.0]\nwidth = 100000"), vec!["huge.toml", "size"]),
        (scene_file(d, "samples.toml", "[[light]]\nkind = \"sphere\"\nposition = [0.0, 4.0, 0.0]\nradius = 0.5\nsamples = -1"), vec!["samples.toml", "samples"]),
        (scene_file(d, "explicit0.toml", "[[light]]\nkind = \"explicit\"\npositions = []"), vec!["explicit0.toml", "positions"]),
        (scene_file(d, "nokind.toml", "[[light]]\nposition = [0.0, 4.0, 0.0]"), vec!["nokind.toml", "kind"]),
        (scene_file(d, "mode.toml", "[shadows]\nmode = \"fast\""), vec!["mode.toml", "fast"]),
        (scene_file(d, "dist.toml", "[[light]]\nkind = \"sphere\"\nposition = [0.0, 4.0, 0.0]\nradius = 0.5\ndistribution = \"gaussian\""), vec!["dist.toml", "gaussian"]),
        (scene_file(d, "lut.toml", "[shadows]\nlut_resolution = 1024"), vec!["lut.toml", "lut_resolution"]),
        (scene_file(d, "texels.toml", "[shadows]\nsoft_light_texels = 100000"), vec!["texels.toml", "soft_light_texels"]),
        (write(d, "nested.toml", "scene = \"other.toml\"\n"), vec!["other.toml"]),
        (write(d, "noglb.toml", "scene = \"nowhere.glb\"\n"), vec!["nowhere.glb"]),
    ];
    std::fs::create_dir(d.join("folder.glb")).unwrap();
    let folder = write(d, "folder.toml", "scene = \"folder.glb\"\n");
    for (p, needles) in cases.iter().chain([(folder, vec!["folder.glb"])].iter()) {
        expect_error(&["render", p, "--quiet"], d, needles);
    }
}

/// A valid one-triangle `.glb` (JSON chunk, then BIN chunk).
fn triangle_glb(json: &str, bin: &[u8]) -> Vec<u8> {
    let mut j = json.as_bytes().to_vec();
    while !j.len().is_multiple_of(4) {
        j.push(b' ');
    }
    let mut b = bin.to_vec();
    while !b.len().is_multiple_of(4) {
        b.push(0);
    }
    let total = 12 + 8 + j.len() + 8 + b.len();
    let mut out = Vec::new();
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(j.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&j);
    out.extend_from_slice(&(b.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&b);
    out
}

const TRIANGLE: [f32; 9] = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];

#[test]
fn corrupt_glb_files_fail_with_named_errors() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // The embedded triangle: buffer 0 without a uri is the BIN chunk.
    let json = triangle_gltf("").replace(r#","uri":"""#, "");
    let good = triangle_glb(&json, &f32_bytes(&TRIANGLE));
    let json_len = u32::from_le_bytes(good[12..16].try_into().unwrap()) as usize;
    let bin_header = 20 + json_len;
    let patch = |at: usize, bytes: &[u8]| {
        let mut b = good.clone();
        b[at..at + bytes.len()].copy_from_slice(bytes);
        b
    };
    let mut not_json = good.clone();
    not_json[20..20 + json_len].fill(b'x');
    let mut rng = 0x2545_f491_4f6c_dd1du64;
    let mut random = |n: usize, prefix: &[u8]| {
        let mut v: Vec<u8> = (0..n)
            .map(|_| {
                rng ^= rng << 13;
                rng ^= rng >> 7;
                rng ^= rng << 17;
                rng as u8
            })
            .collect();
        v[..prefix.len()].copy_from_slice(prefix);
        v
    };
    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        ("magic.glb", patch(0, b"gLTF"), "not a valid glTF"),
        ("version.glb", patch(4, &1u32.to_le_bytes()), "version 1"),
        (
            "length.glb",
            patch(8, &(good.len() as u32 + 100).to_le_bytes()),
            "truncated",
        ),
        (
            "jsonchunk.glb",
            patch(12, &u32::MAX.to_le_bytes()),
            "past the end",
        ),
        (
            "binchunk.glb",
            patch(bin_header, &1000u32.to_le_bytes()),
            "past the end",
        ),
        ("chunktype.glb", patch(16, b"BIN\0"), "not JSON"),
        ("notjson.glb", not_json, "not a valid glTF"),
        ("nobin.glb", good[..bin_header].to_vec(), "truncated"),
        ("random.glb", random(4096, b""), "random.glb"),
        (
            "randomglb.glb",
            random(4096, b"glTF\x02\0\0\0"),
            "randomglb.glb",
        ),
        ("empty.glb", Vec::new(), "empty"),
    ];
    // The unchanged file renders (so the failures are the corruption's).
    let ok = write(d, "ok.glb", &good);
    let sub = tempfile::tempdir().unwrap();
    let o = afs(
        &["render", &ok, "--width", "16", "--height", "16", "--quiet"],
        sub.path(),
    );
    assert!(o.status.success(), "{}", text(&o));
    for (name, bytes, needle) in cases {
        let p = write(d, name, bytes);
        expect_error(&["render", &p, "--quiet"], d, &[name, needle]);
    }
    // A file header that says it is longer than it is, with nothing after it.
    let mut header_only = good[..12].to_vec();
    header_only[8..12].copy_from_slice(&12u32.to_le_bytes());
    let p = write(d, "header.glb", header_only);
    expect_error(&["render", &p, "--quiet"], d, &["header.glb"]);
}

/// A glTF with one indexed triangle: 36 bytes of positions then 6 bytes of
/// u16 `indices`, in `name.bin`; `edit` changes the JSON first.
fn indexed_gltf(
    d: &Path,
    name: &str,
    indices: [u16; 3],
    edit: impl Fn(&mut serde_json::Value),
) -> String {
    let mut bin = f32_bytes(&TRIANGLE);
    bin.extend(indices.iter().flat_map(|i| i.to_le_bytes()));
    write(d, &format!("{name}.bin"), &bin);
    let mut j = serde_json::json!({
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"name": "tri", "primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
            {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}
        ],
        "bufferViews": [{"buffer": 0, "byteLength": 36}, {"buffer": 0, "byteOffset": 36, "byteLength": 6}],
        "buffers": [{"byteLength": 42, "uri": format!("{name}.bin")}]
    });
    edit(&mut j);
    write(d, &format!("{name}.gltf"), j.to_string())
}

#[test]
fn corrupt_gltf_files_fail_with_named_errors() {
    use serde_json::json;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // The unchanged file renders.
    let ok = indexed_gltf(d, "ok", [0, 1, 2], |_| {});
    let sub = tempfile::tempdir().unwrap();
    let o = afs(
        &["render", &ok, "--width", "16", "--height", "16", "--quiet"],
        sub.path(),
    );
    assert!(o.status.success(), "{}", text(&o));

    type Edit = Box<dyn Fn(&mut serde_json::Value)>;
    let same = |_: &mut serde_json::Value| {};
    let cases: Vec<(&str, [u16; 3], Edit, Vec<&str>)> = vec![
        (
            "count",
            [0, 1, 2],
            Box::new(|j| j["accessors"][0]["count"] = json!(4)),
            vec!["tri", "past the end"],
        ),
        (
            "count_huge",
            [0, 1, 2],
            Box::new(|j| j["accessors"][0]["count"] = json!(u32::MAX)),
            vec!["tri", "past the end"],
        ),
        (
            "view",
            [0, 1, 2],
            Box::new(|j| j["bufferViews"][0]["byteLength"] = json!(1000)),
            vec!["tri", "bufferView 0", "past the end"],
        ),
        (
            "view_offset",
            [0, 1, 2],
            Box::new(|j| j["bufferViews"][1]["byteOffset"] = json!(40)),
            vec!["tri", "past the end"],
        ),
        (
            "index",
            [0, 1, 3],
            Box::new(same),
            vec!["tri", "index 3", "out of range"],
        ),
        (
            "index_type",
            [0, 1, 2],
            Box::new(|j| j["accessors"][1]["componentType"] = json!(5126)),
            vec!["tri", "unsigned integer"],
        ),
        (
            "position_type",
            [0, 1, 2],
            Box::new(|j| j["accessors"][0]["componentType"] = json!(5123)),
            vec!["tri", "POSITION", "UNSIGNED_SHORT"],
        ),
        (
            "position_type_invalid",
            [0, 1, 2],
            Box::new(|j| j["accessors"][0]["componentType"] = json!(9999)),
            vec!["componentType"],
        ),
        (
            "position_vec2",
            [0, 1, 2],
            Box::new(|j| j["accessors"][0]["type"] = json!("VEC2")),
            vec!["tri", "VEC3"],
        ),
        (
            "no_buffers",
            [0, 1, 2],
            Box::new(|j| j["buffers"] = json!([])),
            vec!["tri", "buffer 0"],
        ),
        (
            "short_buffer",
            [0, 1, 2],
            Box::new(|j| j["buffers"][0]["byteLength"] = json!(4096)),
            vec!["tri", "byteLength"],
        ),
        (
            "folder_buffer",
            [0, 1, 2],
            Box::new(|j| j["buffers"][0]["uri"] = json!(".")),
            vec!["tri", "not a regular file"],
        ),
        (
            "bad_base64",
            [0, 1, 2],
            Box::new(|j| {
                j["buffers"][0]["uri"] = json!("data:application/octet-stream;base64,@@@@")
            }),
            vec!["tri", "base64"],
        ),
        (
            "remote",
            [0, 1, 2],
            Box::new(|j| j["buffers"][0]["uri"] = json!("https://example.com/tri.bin")),
            vec!["tri", "not supported"],
        ),
        (
            "draco",
            [0, 1, 2],
            Box::new(|j| {
                j["extensionsUsed"] = json!(["KHR_draco_mesh_compression"]);
                j["extensionsRequired"] = json!(["KHR_draco_mesh_compression"]);
            }),
            vec!["KHR_draco_mesh_compression", "not supported"],
        ),
        (
            "meshopt",
            [0, 1, 2],
            Box::new(|j| {
                j["extensionsUsed"] = json!(["EXT_meshopt_compression"]);
                j["extensionsRequired"] = json!(["EXT_meshopt_compression"]);
            }),
            vec!["EXT_meshopt_compression", "not supported"],
        ),
        (
            "version",
            [0, 1, 2],
            Box::new(|j| j["asset"]["version"] = json!("1.0")),
            vec!["1.0"],
        ),
        (
            "no_asset",
            [0, 1, 2],
            Box::new(|j| *j = json!({"scenes": []})),
            vec!["asset"],
        ),
        (
            "cycle",
            [0, 1, 2],
            Box::new(|j| j["nodes"] = json!([{"mesh": 0, "children": [0]}])),
            vec!["not a tree"],
        ),
        // Finite, but too far apart for the f32 GPU passes.
        (
            "far_node",
            [0, 1, 2],
            Box::new(|j| j["nodes"][0]["scale"] = json!([1e30, 1e30, 1e30])),
            vec!["tri", "camera eye"],
        ),
    ];
    for (name, indices, edit, needles) in cases {
        let p = indexed_gltf(d, name, indices, edit);
        let file = format!("{name}.gltf");
        let mut needles = needles;
        needles.push(&file);
        expect_error(&["render", &p, "--quiet"], d, &needles);
    }
    // Not JSON at all.
    let p = write(d, "text.gltf", "this is not JSON");
    expect_error(
        &["render", &p, "--quiet"],
        d,
        &["text.gltf", "not a valid glTF"],
    );
    // Infinite vertices (the NaN one is in bad_gltf_fails_with_named_errors),
    // and finite ones too far apart for the f32 GPU passes.
    for (name, x) in [
        ("inf", f32::INFINITY),
        ("minus_inf", f32::NEG_INFINITY),
        ("far", 1e30),
    ] {
        let mut v = TRIANGLE;
        v[4] = x;
        write(d, &format!("{name}.bin"), f32_bytes(&v));
        let file = format!("{name}.gltf");
        let p = write(d, &file, triangle_gltf(&format!("{name}.bin")));
        let needles = if name == "far" {
            [file.as_str(), "tri", "vertex", "camera eye"]
        } else {
            [file.as_str(), "tri", "vertex 1", "not finite"]
        };
        expect_error(&["render", &p, "--quiet"], d, &needles);
    }
}

#[test]
fn bad_flag_values_fail_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let ps = "builtin:plane_sphere";
    // Rejected by the argument parser (exit code 2), naming the flag.
    for (args, needle) in [
        (vec!["--width=-5"], "--width"),
        (vec!["--width", "abc"], "--width"),
        (vec!["--width", "4294967296"], "--width"),
        (vec!["--height=-1"], "--height"),
        (vec!["--samples=-1"], "--samples"),
        (vec!["--samples", "many"], "--samples"),
        (vec!["--light-texels", "1.5"], "--light-texels"),
        (vec!["--lut-resolution=-3"], "--lut-resolution"),
        (vec!["--mode", "fast"], "--mode"),
        (vec!["--repeat", "0"], "--repeat"),
        (vec!["--repeat", "1001"], "--repeat"),
        (vec!["--dump"], "--dump"),
        (vec!["-o"], "--output"),
        (vec!["--bogus"], "--bogus"),
    ] {
        let mut a = vec!["render", ps, "--quiet"];
        a.extend(args);
        expect_usage_error(&a, d, &[needle]);
    }
    expect_usage_error(&["compare", "only_one"], d, &["DUMP_B"]);
    expect_usage_error(&["export", "builtin:demo"], d, &["--output"]);
    expect_usage_error(&["frobnicate"], d, &["frobnicate"]);

    // Rejected by validation (exit code 1), naming the setting.
    for (args, needles) in [
        (vec!["--width", "100000"], vec!["size", "100000"]),
        (vec!["--height", "0"], vec!["size"]),
        (
            // Past one binding a frame runs in bands and batches; past
            // 4 GiB of view samples it is an error.
            vec!["--width", "16384", "--height", "16384"],
            vec!["view samples", "4 GiB"],
        ),
        (vec!["--light-texels", "0"], vec!["light_texels"]),
        (vec!["--light-texels", "100000"], vec!["light_texels"]),
        (vec!["--lut-resolution", "0"], vec!["lut_resolution"]),
        (vec!["--lut-resolution", "1024"], vec!["lut_resolution"]),
        (vec!["--device", "no such device"], vec!["no such device"]),
    ] {
        let mut a = vec!["render", ps, "--quiet"];
        a.extend(args);
        expect_error(&a, d, &needles);
    }
    // The CPU reference: an image it cannot hold is an error, not an
    // allocation failure.
    expect_error(
        &[
            "reference",
            ps,
            "--width",
            "16384",
            "--height",
            "16384",
            "--quiet",
        ],
        d,
        &["size", "16384x16384"],
    );
    // Scene arguments.
    expect_error(
        &["render", "builtin:torus_knot:abc", "--quiet"],
        d,
        &["torus_knot", "abc"],
    );
    expect_error(
        &["render", "builtin:torus_knot:10000000000", "--quiet"],
        d,
        &["torus_knot"],
    );
    expect_error(&["render", "scene.obj", "--quiet"], d, &["scene.obj"]);
    expect_error(&["render", "", "--quiet"], d, &["builtin:NAME"]);
    // compare and export.
    expect_error(&["compare", "no_dump", "no_dump"], d, &["no_dump"]);
    expect_error(
        &["export", "builtin:nonsense", "-o", "x.glb"],
        d,
        &["nonsense"],
    );
    expect_error(
        &["export", "builtin:torus_knot:1", "-o", "x.glb"],
        d,
        &["torus_knot"],
    );
    expect_error(
        &["export", "builtin:demo", "-o", "no/such/folder/x.glb"],
        d,
        &["no/such/folder/x.glb"],
    );
}

#[test]
fn failed_runs_leave_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let small = ["--width", "8", "--height", "8", "--quiet"];
    let args = |extra: &[&'static str]| {
        let mut a = vec!["render", "builtin:plane_sphere"];
        a.extend(small);
        a.extend(extra);
        a
    };
    // The frame renders, then the dump cannot be written: the image, which
    // was written first, must not be left looking like a finished run.
    write(d, "a_file", "not a folder");
    expect_error(
        &args(&["-o", "img.png", "--dump", "a_file"]),
        d,
        &["a_file"],
    );
    expect_error(
        &args(&["-o", "img.png", "--dump", "a_file/dump"]),
        d,
        &["a_file"],
    );
    // The image path is a folder, or its folder cannot be made.
    std::fs::create_dir(d.join("folder.png")).unwrap();
    expect_error(&args(&["-o", "folder.png"]), d, &["folder.png"]);
    assert!(d.join("folder.png").read_dir().unwrap().next().is_none());
    expect_error(&args(&["-o", "a_file/img.png"]), d, &["a_file"]);
    // Nothing half-written anywhere.
    let names: Vec<String> = std::fs::read_dir(d)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(
        names.iter().all(|n| n == "a_file" || n == "folder.png"),
        "{names:?}"
    );
    // And a run that succeeds leaves exactly its outputs.
    let o = afs(&args(&["-o", "img.png", "--dump", "dump"]), d);
    assert!(o.status.success(), "{}", text(&o));
    assert!(d.join("img.png").is_file());
    assert!(!d.join(".partial-output.img.png").exists());
}

/// `-o` inside the `--dump` folder: its `image.png` is the dump's own
/// picture and both are written; another of the dump's files is refused up
/// front, leaving nothing behind.
#[test]
fn output_inside_the_dump_folder() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let args = |extra: &[&'static str]| {
        let mut a = vec![
            "render",
            "builtin:plane_sphere",
            "--width",
            "24",
            "--height",
            "16",
            "--quiet",
        ];
        a.extend_from_slice(extra);
        a
    };
    let o = afs(&args(&["--dump", "dump", "-o", "dump/image.png"]), d);
    assert!(o.status.success(), "{}", text(&o));
    let img = image::open(d.join("dump/image.png")).unwrap();
    assert_eq!((img.width(), img.height()), (24, 16));
    assert_complete_dump(&d.join("dump"));
    // The same through another spelling of the folder.
    let o = afs(&args(&["--dump", "./dump2", "-o", "dump2/./image.png"]), d);
    assert!(o.status.success(), "{}", text(&o));
    assert!(d.join("dump2/image.png").is_file());
    // Another file of the dump: refused before anything is written.
    expect_error(
        &args(&["--dump", "dump3", "-o", "dump3/scene.json"]),
        d,
        &["would overwrite the dump's own scene.json"],
    );
    assert!(!d.join("dump3").exists());
}

/// `--light` gives a glTF soft shadows without a scene file: the stats show
/// the soft path with the asked samples; a bad spec is a named error.
#[test]
fn light_flag_replaces_the_scene_lights() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write(
        d,
        "tri.bin",
        f32_bytes(&[0., 0., 0., 1., 0., 0., 0., 1., 0.]),
    );
    let gltf = write(d, "tri.gltf", triangle_gltf("tri.bin"));
    // A soft frame of the triangle on a ground, with `extra` flags: its
    // statistics.
    let soft_stats = |extra: &[&str]| -> serde_json::Value {
        let mut args = vec![
            "render",
            gltf.as_str(),
            "--ground",
            "--light",
            "sphere:samples=8",
            "--width",
            "24",
            "--height",
            "24",
            "--stats",
            "--quiet",
            "-o",
            "soft.png",
        ];
        args.extend_from_slice(extra);
        let o = afs(&args, d);
        assert!(o.status.success(), "{}", text(&o));
        let out = String::from_utf8_lossy(&o.stdout);
        serde_json::from_str(&out[out.find('{').unwrap()..]).unwrap()
    };
    let stats = soft_stats(&[]);
    let light = &stats["lights"][0];
    assert_eq!(light["path"], "gpu soft shadows", "{light}");
    assert_eq!(light["stats"]["light_samples"], 8, "{light}");
    // The light texels: auto by default, resolved per frame (a tiny frame
    // of three triangles takes the least); a number on the command line.
    assert_eq!(stats["settings"]["soft_light_texels"], "auto", "{stats}");
    assert_eq!(light["stats"]["light_texels"], 32, "{light}");
    let stats = soft_stats(&["--light-texels", "40"]);
    assert_eq!(stats["settings"]["soft_light_texels"], 40, "{stats}");
    assert_eq!(stats["lights"][0]["stats"]["light_texels"], 40, "{stats}");
    expect_error(
        &["render", &gltf, "--light", "lamp", "-o", "x.png"],
        d,
        &["--light lamp", "unknown kind \"lamp\""],
    );
}

/// `--frames N`: the dump holds the mean of N frames, each frame's own dump
/// in `frame-NNN` and every frame's samples in `scene.json`; `afs
/// reference --frames N` writes the oracle's frames with the same samples;
/// `--frames` with `--repeat` is refused.
#[test]
fn frames_accumulate_into_the_dump() {
    use alias_free_shadows::dump::Dump;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let common = [
        "builtin:demo",
        "--width",
        "24",
        "--height",
        "24",
        "--samples",
        "16",
        "--frames",
        "3",
        "--quiet",
    ];
    let run = |cmd: &str, dump: &str| {
        let mut a = vec![cmd];
        a.extend_from_slice(&common);
        a.extend_from_slice(&["--dump", dump, "-o", "x.png"]);
        let o = afs(&a, d);
        assert!(o.status.success(), "{}", text(&o));
    };
    run("render", "gpu");
    run("reference", "oracle");
    let mean = Dump::read(&d.join("gpu")).unwrap();
    assert_complete_dump(&d.join("gpu"));
    assert_eq!(mean.scene.frames.len(), 3);
    let mut sums = vec![0.0f64; mean.visibility[0].len()];
    for f in 0..3 {
        let name = format!("frame-{f:03}");
        assert_complete_dump(&d.join("gpu").join(&name));
        let frame = Dump::read(&d.join("gpu").join(&name)).unwrap();
        let oracle = Dump::read(&d.join("oracle").join(&name)).unwrap();
        assert!(frame.scene.frames.is_empty());
        assert_eq!(
            frame.scene.lights, mean.scene.frames[f],
            "{name}: samples listed"
        );
        assert_eq!(
            frame.scene.lights[0].samples, oracle.scene.lights[0].samples,
            "{name}: the oracle's frame has the same samples"
        );
        for (s, p) in sums.iter_mut().zip(&frame.visibility[0]) {
            *s += p[0] as f64;
        }
    }
    assert_ne!(
        mean.scene.frames[0][0].samples,
        mean.scene.frames[1][0].samples
    );
    for (s, p) in sums.iter().zip(&mean.visibility[0]) {
        assert_eq!(p[0], (s / 3.0) as f32);
    }
    expect_error(
        &["render", "builtin:demo", "--frames", "2", "--repeat", "2"],
        d,
        &["--frames and --repeat do not go together"],
    );
    expect_error(
        &[
            "render",
            "builtin:demo",
            "--frames",
            "2",
            "--dump",
            "other",
            "-o",
            "other/frame-001/image.png",
        ],
        d,
        &["inside --dump other's per-frame folders"],
    );
}
