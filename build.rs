//! SPIR-V for every shader in `shaders/`.
//!
//! Users of the crate build nothing: the SPIR-V is committed in
//! `shaders/spirv/` and this script only generates `$OUT_DIR/shaders.rs`,
//! one `pub const NAME: &[u32]` per shader (`include_bytes!` of its file).
//! Compute shaders keep their names (`scan_block.comp` -> `SCAN_BLOCK`),
//! graphics stages get the stage as a suffix (`view_samples.vert` ->
//! `VIEW_SAMPLES_VERT`), and variants compiled with definitions get their own
//! constants (`VARIANTS`).
//!
//! With the `compile-shaders` feature (developers and CI) it compiles every
//! shader with `shaderc` (GLSL 450, Vulkan 1.2, SPIR-V 1.5), marks its float
//! arithmetic `NoContraction` (`no_contraction`: no fused multiply-adds on any
//! driver), and rewrites the files in `shaders/spirv/` that differ, with `shaders/spirv/SOURCES`, the
//! hash of every source the SPIR-V came from. A compile error fails the build
//! with shaderc's message, which names the shader (or header) and line.
//!
//! Without the feature, a shader source whose hash differs from `SOURCES`
//! fails the build with the names of the changed files, so that an edited
//! shader is never run as its stale SPIR-V.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Extra compilations of a shader with preprocessor definitions, for code
/// that must be compiled out rather than skipped by a branch (lavapipe pays
/// for guarded code it does not run): (a compute shader's stem or a
/// graphics stage's file name, constant, definitions).
type Variant = (
    &'static str,
    &'static str,
    &'static [(&'static str, &'static str)],
);
const VARIANTS: &[Variant] = &[
    (
        "view_samples.frag",
        "VIEW_SAMPLES_OPAQUE_FRAG",
        &[("OPAQUE", "1")],
    ),
    (
        "tile_bin_units",
        "TILE_BIN_UNITS_SAMPLE_LANES",
        &[("SAMPLE_LANES", "1")],
    ),
    ("soft_occlusion", "SOFT_OCCLUSION_EXACT", &[("EXACT", "1")]),
    (
        "soft_occlusion",
        "SOFT_OCCLUSION_LUT1",
        &[("LUT_BLOCKS", "1")],
    ),
    (
        "soft_occlusion",
        "SOFT_OCCLUSION_LUT2",
        &[("LUT_BLOCKS", "2")],
    ),
    (
        "soft_occlusion",
        "SOFT_OCCLUSION_LUT3",
        &[("LUT_BLOCKS", "3")],
    ),
    (
        "soft_occlusion",
        "SOFT_OCCLUSION_LUT4",
        &[("LUT_BLOCKS", "4")],
    ),
    (
        "soft_occlusion",
        "SOFT_OCCLUSION_LUT5",
        &[("LUT_BLOCKS", "5")],
    ),
    (
        "soft_occlusion",
        "SOFT_OCCLUSION_LUT6",
        &[("LUT_BLOCKS", "6")],
    ),
    (
        "soft_occlusion",
        "SOFT_OCCLUSION_LUT7",
        &[("LUT_BLOCKS", "7")],
    ),
    (
        "soft_occlusion",
        "SOFT_OCCLUSION_LUT8",
        &[("LUT_BLOCKS", "8")],
    ),
    (
        "soft_occlusion",
        "SOFT_OCCLUSION_SURE1",
        &[("LUT_BLOCKS", "1"), ("SURE", "1")],
    ),
    (
        "soft_occlusion",
        "SOFT_OCCLUSION_SURE2",
        &[("LUT_BLOCKS", "2"), ("SURE", "1")],
    ),
    (
        "soft_occlusion",
        "SOFT_OCCLUSION_SURE3",
        &[("LUT_BLOCKS", "3"), ("SURE", "1")],
    ),
    (
        "soft_occlusion",
        "SOFT_OCCLUSION_SURE4",
        &[("LUT_BLOCKS", "4"), ("SURE", "1")],
    ),
    (
        "soft_occlusion",
        "SOFT_OCCLUSION_SURE5",
        &[("LUT_BLOCKS", "5"), ("SURE", "1")],
    ),
    (
        "soft_occlusion",
        "SOFT_OCCLUSION_SURE6",
        &[("LUT_BLOCKS", "6"), ("SURE", "1")],
    ),
    (
        "soft_occlusion",
        "SOFT_OCCLUSION_SURE7",
        &[("LUT_BLOCKS", "7"), ("SURE", "1")],
    ),
    (
        "soft_occlusion",
        "SOFT_OCCLUSION_SURE8",
        &[("LUT_BLOCKS", "8"), ("SURE", "1")],
    ),
];

/// One SPIR-V file: the source it is compiled from, with which definitions.
struct Build {
    #[cfg_attr(not(feature = "compile-shaders"), allow(dead_code))]
    source: PathBuf,
    ext: String,
    stem: String,
    spv_name: String,
    const_name: String,
    defines: Vec<(&'static str, &'static str)>,
}

/// Options that change the SPIR-V without changing a source file: part of
/// the hash, so that changing them here asks for a recompile too.
const COMPILE_OPTIONS: &str = "glsl450 vulkan1.2 spirv1.5 performance warnings-as-errors";

fn main() {
    let manifest = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").expect("CARGO_MANIFEST_DIR"));
    let shader_dir = manifest.join("shaders");
    let spirv_dir = shader_dir.join("spirv");
    let out_dir = PathBuf::from(std::env::var("OUT_DIR").expect("OUT_DIR"));

    // Watching the folders catches added and removed files, the files catch edits.
    println!("cargo:rerun-if-changed={}", shader_dir.display());
    println!("cargo:rerun-if-changed={}", spirv_dir.display());

    let mut entries: Vec<PathBuf> = std::fs::read_dir(&shader_dir)
        .unwrap_or_else(|e| panic!("cannot read {}: {e}", shader_dir.display()))
        .map(|e| e.expect("shader directory entry").path())
        .filter(|p| p.is_file())
        .collect();
    entries.sort();
    for path in &entries {
        println!("cargo:rerun-if-changed={}", path.display());
    }
    let builds = builds(&entries);
    let sources = sources_manifest(&entries);

    #[cfg(feature = "compile-shaders")]
    compile_all(&shader_dir, &spirv_dir, &builds, &sources);
    #[cfg(not(feature = "compile-shaders"))]
    check_sources(&spirv_dir, &sources);

    let mut generated = String::from(
        "// Generated by build.rs from shaders/spirv/*.spv: SPIR-V words per shader.\n\n",
    );
    for build in &builds {
        let spv_path = spirv_dir.join(&build.spv_name);
        let len = std::fs::metadata(&spv_path)
            .unwrap_or_else(|e| {
                panic!(
                    "{}: {e}; build with `--features compile-shaders` to compile it",
                    spv_path.display()
                )
            })
            .len();
        assert!(
            len > 0 && len % 4 == 0,
            "{} is not SPIR-V ({len} bytes)",
            spv_path.display()
        );
        let with: Vec<String> = build
            .defines
            .iter()
            .map(|(k, v)| format!("{k}={v}"))
            .collect();
        if with.is_empty() {
            writeln!(
                generated,
                "/// SPIR-V of `shaders/{}.{}`.",
                build.stem, build.ext
            )
            .unwrap();
        } else {
            writeln!(
                generated,
                "/// SPIR-V of `shaders/{}.{}` with {}.",
                build.stem,
                build.ext,
                with.join(", ")
            )
            .unwrap();
        }
        writeln!(
            generated,
            "pub const {}: &[u32] = {{\n    static BYTES: Aligned<{len}> = Aligned(*include_bytes!({:?}));\n    words(&BYTES)\n}};\n",
            build.const_name,
            spv_path.display().to_string(),
        )
        .unwrap();
    }
    let target = out_dir.join("shaders.rs");
    std::fs::write(&target, generated)
        .unwrap_or_else(|e| panic!("cannot write {}: {e}", target.display()));
}

/// Every SPIR-V file the crate carries, in a fixed order.
fn builds(entries: &[PathBuf]) -> Vec<Build> {
    let mut builds = Vec::new();
    for path in entries {
        let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
        if !matches!(ext, "comp" | "vert" | "frag") {
            continue;
        }
        let stem = path.file_stem().unwrap().to_string_lossy().to_string();
        let (spv_name, name) = if ext == "comp" {
            (format!("{stem}.spv"), const_name(&stem))
        } else {
            (
                format!("{stem}.{ext}.spv"),
                const_name(&format!("{stem}_{ext}")),
            )
        };
        builds.push(Build {
            source: path.clone(),
            ext: ext.to_string(),
            stem: stem.clone(),
            spv_name,
            const_name: name,
            defines: Vec::new(),
        });
        // A compute shader's variants name its stem, a graphics stage's
        // its file name (`view_samples.frag`).
        let file = format!("{stem}.{ext}");
        let of_this = |v: &&Variant| match ext {
            "comp" => v.0 == stem,
            _ => v.0 == file,
        };
        for (v_stem, v_name, defines) in VARIANTS.iter().filter(of_this) {
            builds.push(Build {
                source: path.clone(),
                ext: ext.to_string(),
                stem: stem.clone(),
                spv_name: format!("{v_stem}.{}.spv", v_name.to_lowercase()),
                const_name: v_name.to_string(),
                defines: defines.to_vec(),
            });
        }
    }
    builds
}

/// `SOURCES`: one line per shader source and header (`hash name`), then the
/// hash of the variants and compile options. Line ends are normalised, so a
/// checkout with CRLF hashes as one with LF.
fn sources_manifest(entries: &[PathBuf]) -> String {
    let mut manifest = String::from(
        "# FNV-1a 64 of each source in shaders/ that shaders/spirv/*.spv was compiled from\n",
    );
    for path in entries {
        let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
        if !matches!(ext, "comp" | "vert" | "frag" | "glsl") {
            continue;
        }
        let text = std::fs::read_to_string(path)
            .unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
        let name = path.file_name().unwrap().to_string_lossy();
        writeln!(
            manifest,
            "{:016x} {name}",
            fnv1a(&text.replace("\r\n", "\n"))
        )
        .unwrap();
    }
    let options = format!("{COMPILE_OPTIONS} {VARIANTS:?}");
    writeln!(
        manifest,
        "{:016x} (build.rs: options and variants)",
        fnv1a(&options)
    )
    .unwrap();
    manifest
}

fn fnv1a(text: &str) -> u64 {
    text.bytes().fold(0xcbf2_9ce4_8422_2325, |h, b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

/// Without a compiler: the committed SPIR-V must come from these sources.
#[cfg(not(feature = "compile-shaders"))]
fn check_sources(spirv_dir: &Path, sources: &str) {
    let path = spirv_dir.join("SOURCES");
    let committed = std::fs::read_to_string(&path)
        .unwrap_or_default()
        .replace("\r\n", "\n");
    if committed == sources {
        return;
    }
    let old: std::collections::HashSet<&str> = committed.lines().collect();
    let changed: Vec<&str> = sources
        .lines()
        .filter(|l| !old.contains(l))
        .filter_map(|l| l.split_once(' ').map(|(_, name)| name))
        .collect();
    let new: std::collections::HashSet<&str> = sources.lines().collect();
    let removed: Vec<&str> = committed
        .lines()
        .filter(|l| !l.starts_with('#') && !new.contains(l))
        .filter_map(|l| l.split_once(' ').map(|(_, name)| name))
        .filter(|name| !changed.contains(name))
        .collect();
    panic!(
        "the SPIR-V in {} is stale: changed since it was compiled: {}{}. \
         Build once with `--features compile-shaders` (it compiles shaders/ with shaderc and \
         rewrites shaders/spirv/), then commit shaders/spirv/.",
        spirv_dir.display(),
        changed.join(", "),
        if removed.is_empty() {
            String::new()
        } else {
            format!("; removed: {}", removed.join(", "))
        }
    );
}

/// Compiles every build and rewrites the committed files that differ; files
/// of shaders that no longer exist are removed.
#[cfg(feature = "compile-shaders")]
fn compile_all(shader_dir: &Path, spirv_dir: &Path, builds: &[Build], sources: &str) {
    std::fs::create_dir_all(spirv_dir)
        .unwrap_or_else(|e| panic!("cannot create {}: {e}", spirv_dir.display()));
    let compiler = shaderc::Compiler::new().expect("cannot create the shaderc compiler");
    let mut errors = Vec::new();
    for build in builds {
        let kind = match build.ext.as_str() {
            "comp" => shaderc::ShaderKind::Compute,
            "vert" => shaderc::ShaderKind::Vertex,
            _ => shaderc::ShaderKind::Fragment,
        };
        match compile(&compiler, shader_dir, &build.source, kind, &build.defines) {
            Ok(words) => {
                let words = no_contraction(&words);
                let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
                write_if_changed(&spirv_dir.join(&build.spv_name), bytes.as_slice());
            }
            Err(message) => errors.push(message),
        }
    }
    if !errors.is_empty() {
        // Cargo shows the panic message: every error with its file and line.
        panic!("shader compilation failed:\n{}", errors.join("\n"));
    }
    let keep: std::collections::HashSet<&str> =
        builds.iter().map(|b| b.spv_name.as_str()).collect();
    for entry in std::fs::read_dir(spirv_dir).expect("shaders/spirv") {
        let path = entry.expect("shaders/spirv entry").path();
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        if name.ends_with(".spv") && !keep.contains(name.as_str()) {
            std::fs::remove_file(&path)
                .unwrap_or_else(|e| panic!("cannot remove {}: {e}", path.display()));
        }
    }
    write_if_changed(&spirv_dir.join("SOURCES"), sources.as_bytes());
}

/// Writes only what changed, so that an unchanged build leaves the watched
/// folder alone (a write would make cargo run this script again).
#[cfg(feature = "compile-shaders")]
fn write_if_changed(path: &Path, bytes: &[u8]) {
    if std::fs::read(path).ok().as_deref() == Some(bytes) {
        return;
    }
    std::fs::write(path, bytes).unwrap_or_else(|e| panic!("cannot write {}: {e}", path.display()));
}

#[cfg(feature = "compile-shaders")]
/// Compiles one shader of stage `kind`; the error carries the shader's path and line.
fn compile(
    compiler: &shaderc::Compiler,
    shader_dir: &Path,
    path: &Path,
    kind: shaderc::ShaderKind,
    defines: &[(&str, &str)],
) -> Result<Vec<u32>, String> {
    let source = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut options = shaderc::CompileOptions::new().map_err(|e| e.to_string())?;
    // Vulkan 1.2 guarantees SPIR-V 1.5, which lavapipe and every 1.2 driver consume.
    options.set_target_env(
        shaderc::TargetEnv::Vulkan,
        shaderc::EnvVersion::Vulkan1_2 as u32,
    );
    options.set_target_spirv(shaderc::SpirvVersion::V1_5);
    options.set_source_language(shaderc::SourceLanguage::GLSL);
    options.set_optimization_level(shaderc::OptimizationLevel::Performance);
    options.set_warnings_as_errors();
    for (k, v) in defines {
        options.add_macro_definition(k, Some(v));
    }
    let include_dir = shader_dir.to_path_buf();
    options.set_include_callback(move |requested, _kind, requesting, _depth| {
        // Headers are looked up next to the including file first, then in shaders/.
        let beside = Path::new(requesting)
            .parent()
            .map(|p| p.join(requested))
            .filter(|p| p.is_file());
        let resolved = beside.unwrap_or_else(|| include_dir.join(requested));
        let content = std::fs::read_to_string(&resolved).map_err(|e| {
            format!(
                "cannot include \"{requested}\" from {requesting} ({}): {e}",
                resolved.display()
            )
        })?;
        println!("cargo:rerun-if-changed={}", resolved.display());
        Ok(shaderc::ResolvedInclude {
            resolved_name: resolved.display().to_string(),
            content,
        })
    });

    let name = path.display().to_string();
    let artifact = compiler
        .compile_into_spirv(&source, kind, &name, "main", Some(&options))
        .map_err(|e| match e {
            // shaderc's lines read "<path>:<line>: error: ..."; the header
            // names which shader an error in an included file came from.
            shaderc::Error::CompilationError(count, text) => {
                format!("{name}: {count} error(s):\n{}", text.trim_end())
            }
            other => format!("{name}: {other}"),
        })?;
    Ok(artifact.as_binary().to_vec())
}

/// Decorates every float arithmetic result with `NoContraction`, as if every
/// GLSL expression were `precise`: a driver may not fuse a multiply and an
/// add into one rounding (NVIDIA's does, lavapipe's does not), so that add,
/// subtract and multiply round as IEEE says on every device and the GPU's
/// bits equal the CPU twins' (measured on an H200: one-ulp windows, masks
/// of look-up mode one word off exact mode, before this).
#[cfg(feature = "compile-shaders")]
fn no_contraction(words: &[u32]) -> Vec<u32> {
    const OP_DECORATE: u32 = 71;
    const NO_CONTRACTION: u32 = 42;
    // OpFNegate, OpFAdd, OpFSub, OpFMul, OpFDiv, OpFRem, OpFMod,
    // OpVectorTimesScalar .. OpOuterProduct, OpDot.
    const ARITHMETIC: &[u32] = &[
        127, 129, 131, 133, 136, 140, 141, 142, 143, 144, 145, 146, 147, 148,
    ];
    // OpDecorate .. OpGroupMemberDecorate, OpDecorateId, OpDecorateString,
    // OpMemberDecorateString: the annotation section.
    const ANNOTATION: &[u32] = &[71, 72, 73, 74, 75, 332, 5632, 5633];
    let mut decorated = std::collections::HashSet::new();
    let mut targets = Vec::new();
    let mut after_annotations = None;
    let mut at = 5; // after the header
    while at < words.len() {
        let count = (words[at] >> 16) as usize;
        let op = words[at] & 0xffff;
        assert!(
            count > 0 && at + count <= words.len(),
            "malformed SPIR-V at word {at}"
        );
        if ANNOTATION.contains(&op) {
            after_annotations = Some(at + count);
            if op == OP_DECORATE && words[at + 2] == NO_CONTRACTION {
                decorated.insert(words[at + 1]);
            }
        } else if ARITHMETIC.contains(&op) {
            targets.push(words[at + 2]);
        }
        at += count;
    }
    let insert = after_annotations.expect("every shader has decorations (its bindings)");
    let mut out = words[..insert].to_vec();
    for id in targets.into_iter().filter(|id| !decorated.contains(id)) {
        out.extend([(3 << 16) | OP_DECORATE, id, NO_CONTRACTION]);
    }
    out.extend_from_slice(&words[insert..]);
    out
}

/// `scan_block` -> `SCAN_BLOCK`.
fn const_name(stem: &str) -> String {
    stem.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() {
                c.to_ascii_uppercase()
            } else {
                '_'
            }
        })
        .collect()
}
