//! `afs`: the alias-free shadows command-line tool.
//!
//! Its doc comments are clap's `--help` text, where `[shadows]` names a
//! TOML table, not a link.
#![allow(rustdoc::broken_intra_doc_links)]

use std::path::PathBuf;
use std::process::ExitCode;

use alias_free_shadows::dump::{compare, Dump};
use alias_free_shadows::render::{render_reference, Accumulator, Engine, Frame, FrameOptions};
use alias_free_shadows::scene::file::{self, LightTexels, SceneDescription, SoftMode};
use alias_free_shadows::shade::ShadingNormals;
use alias_free_shadows::vulkan::ContextOptions;
use alias_free_shadows::{scene, vulkan, Error, Result};
use clap::{Args, Parser, Subcommand};

/// Alias-free shadows: pixel-exact hard shadows and sample-exact soft shadows
/// computed with alias-free shadow maps on Vulkan compute (Sintorn,
/// Eisemann, Assarsson, EGSR 2008).
///
/// A SCENE is a TOML scene file (see the README), a .gltf or .glb file, or
/// builtin:NAME where NAME is one of demo, plane_sphere, torus_knot[:TRIANGLES],
/// columns, hairball, fence, stairs. Without a SCENE, builtin:demo is used.
#[derive(Parser, Debug)]
#[command(name = "afs", version, about, long_about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Render a scene's shadows on the GPU and write the shaded image (and optionally a dump).
    ///
    /// Point and directional lights use the alias-free hard-shadow passes;
    /// lights with extent (sphere, ellipsoid, disk, rect, explicit samples)
    /// the soft-shadow passes: light-sample bitmasks from a plane look-up
    /// texture that bounds each plane's bits, with the unsure light samples
    /// tested exactly (`--mode lut`, the default: the masks of exact mode),
    /// from testing every light sample (`--mode exact`), or from the
    /// nearest texel's plane alone (`--mode approx`, the paper's look-up:
    /// faster, wrong near planes). Look-up mode's table is kept across runs
    /// in `$XDG_CACHE_HOME/alias-free-shadows` (or `~/.cache/...`; set
    /// `AFS_TABLE_CACHE` to another folder, or to 0 to keep none).
    Render(RenderArgs),
    /// Render a scene with the CPU ray-casting oracle (the reference).
    Reference(RenderArgs),
    /// Compare the visibility of two dumps: mean absolute, RMSE and maximum
    /// difference and the share of pixels differing by more than one light sample.
    Compare {
        /// The first dump folder.
        dump_a: PathBuf,
        /// The second dump folder.
        dump_b: PathBuf,
        /// Print the comparison as JSON.
        #[arg(long)]
        json: bool,
    },
    /// List the Vulkan devices and their limits.
    Info,
    /// Run time against error: our soft shadows and the baselines (shadow
    /// map + PCF, PCSS, one shadow map per light sample, the CPU oracle,
    /// and Embree's shadow rays in a build with the `embree` feature) over
    /// their parameters, against a converged oracle image, plus our hard
    /// shadows against one shadow map (and Embree); writes bench.csv,
    /// bench.png and bench-ratios.md (the key ratios, also printed).
    Bench(BenchArgs),
    /// Write a built-in scene as a binary glTF (.glb) file.
    Export {
        /// The built-in scene, e.g. builtin:demo or torus_knot:20000.
        scene: String,
        /// The .glb file to write.
        #[arg(short, long)]
        output: PathBuf,
    },
}

#[derive(Args, Debug)]
struct BenchArgs {
    /// Folder for bench.csv, bench.png and bench-ratios.md.
    #[arg(long, default_value = "docs")]
    out: PathBuf,
    /// Image width and height (default 256, 32 with --quick).
    #[arg(long)]
    size: Option<u32>,
    /// A tiny sweep on one scene, for tests.
    #[arg(long)]
    quick: bool,
    /// Comma-separated scenes (default: builtin:demo, builtin:plane_sphere,
    /// builtin:torus_knot:20000 and the Lantern of ../shared/assets when present;
    /// with --quick builtin:plane_sphere).
    #[arg(long, value_delimiter = ',')]
    scenes: Option<Vec<String>>,
    /// Timed runs per configuration; the median is reported (default 3, 1 with --quick).
    #[arg(long)]
    repeats: Option<u32>,
    /// Light samples of the converged oracle image (default 4096, 256 with --quick).
    #[arg(long)]
    reference_samples: Option<u32>,
    /// Use the Vulkan device whose name contains this text (also AFS_DEVICE).
    #[arg(long, env = "AFS_DEVICE")]
    device: Option<String>,
    /// Do not show the progress bar.
    #[arg(long)]
    quiet: bool,
}

#[derive(Args, Debug)]
struct RenderArgs {
    /// The scene: a .toml scene file, a .gltf/.glb file, or builtin:NAME.
    #[arg(default_value = "builtin:demo")]
    scene: String,
    /// Where to write the shaded image (PNG).
    #[arg(short, long, default_value = "out.png")]
    output: PathBuf,
    /// Also write the dump (EXR view samples and visibility, scene.json,
    /// stats.json, image.png) into this folder.
    #[arg(long, value_name = "DIR")]
    dump: Option<PathBuf>,
    /// Print the statistics (times per pass and counters).
    #[arg(long)]
    stats: bool,
    /// Override the image width.
    #[arg(long)]
    width: Option<u32>,
    /// Override the image height.
    #[arg(long)]
    height: Option<u32>,
    /// Override the number of samples of every area or volumetric light (1 to 1024).
    #[arg(long)]
    samples: Option<u32>,
    /// Replace the scene's lights with one light: KIND[:KEY=VALUE,...], KIND
    /// point, directional, sphere, disk or rect; keys radius (default a
    /// tenth of the light's distance to the scene), samples (default 128) and
    /// rotate (true: each pixel sees the sphere's or disk's samples turned by
    /// its own angle, which turns banding into noise; default false).
    /// It stands where the scene's first light is and faces the scene, e.g.
    /// `--light sphere` or `--light disk:radius=0.2,samples=256` for soft
    /// shadows from a glTF without a scene file.
    #[arg(long, value_name = "SPEC")]
    light: Option<String>,
    /// Light-texel map resolution, texels per side of each light face:
    /// `auto` (chosen per frame from the view samples and triangles) or a
    /// number; only speed depends on it (overrides [shadows] light_texels
    /// and soft_light_texels).
    #[arg(long, value_name = "N|auto")]
    light_texels: Option<LightTexels>,
    /// Soft-shadow mode: lut (exact masks through the look-up texture, the
    /// default), exact (every light sample tested) or approx (nearest-texel
    /// look-up) (overrides [shadows] mode).
    #[arg(long, value_parser = ["lut", "exact", "approx"])]
    mode: Option<String>,
    /// Plane look-up texture resolution (overrides [shadows] lut_resolution).
    #[arg(long)]
    lut_resolution: Option<u32>,
    /// Turn the view-sample clusters off (tile binning then keeps casters
    /// that cannot shadow a tile's samples; the same result, slower: for
    /// measuring what the clusters save) (overrides [shadows] clusters).
    #[arg(long)]
    no_clusters: bool,
    /// Turn soft occlusion's wedge rule off (casters whose cone from a view
    /// sample passes the light's sphere then go on to the per-light-sample
    /// tests; the same result, slower: for measuring what the rule saves;
    /// exact mode only, look-up mode never runs it)
    /// (overrides [shadows] wedge_rule).
    #[arg(long)]
    no_wedge_rule: bool,
    /// Use the Vulkan device whose name contains this text (also AFS_DEVICE).
    #[arg(long, env = "AFS_DEVICE")]
    device: Option<String>,
    /// Add a ground plane under the scene's lowest point.
    #[arg(long)]
    ground: bool,
    /// Treat alpha-tested (MASK and BLEND) materials as opaque: no holes to
    /// see or cast through (to measure what the alpha tests cost, or to see
    /// a model as engines that ignore its masks do).
    #[arg(long)]
    opaque_masks: bool,
    /// Do not show progress bars.
    #[arg(long)]
    quiet: bool,
    /// Render the frame this many times and report the last one (the first
    /// frame pays for pipeline compilation; later ones show warm timings,
    /// whose median, least and greatest times are printed too).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=1000))]
    repeat: u32,
    /// Temporal jitter (paper §4.2): render this many frames, each with
    /// fresh light samples (every light's seed mixed with the frame's
    /// index; frame 0 is the plain frame), and write their mean visibility,
    /// which converges to the visibility of all their samples together.
    /// With --dump, DIR holds the mean (its scene.json lists every frame's
    /// samples) and DIR/frame-000, ... each frame's own dump, exact for its
    /// samples: `afs reference` with the same --frames writes the oracle's.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=1024))]
    frames: u32,
}

impl RenderArgs {
    fn scene(&self) -> Result<SceneDescription> {
        let mut desc = file::load(&self.scene)?;
        if self.ground {
            file::place_on_ground(&mut desc.scene);
        }
        if self.opaque_masks {
            for m in &mut desc.scene.materials {
                m.alpha_mode = alias_free_shadows::scene::AlphaMode::Opaque;
            }
        }
        if let Some(spec) = &self.light {
            file::replace_light(&mut desc, spec)?;
        }
        if let Some(w) = self.width {
            desc.camera.width = w;
        }
        if let Some(h) = self.height {
            desc.camera.height = h;
        }
        if let Some(s) = self.samples {
            for l in desc.lights.iter_mut().filter(|l| l.is_area()) {
                if !matches!(
                    l.shape,
                    alias_free_shadows::light::LightShape::Explicit { .. }
                ) {
                    l.samples = s;
                }
            }
        }
        if let Some(t) = self.light_texels {
            desc.shadows.light_texels = t;
            desc.shadows.soft_light_texels = t;
        }
        if let Some(m) = &self.mode {
            desc.shadows.mode = if m == "exact" {
                SoftMode::Exact
            } else if m == "approx" {
                SoftMode::Approx
            } else {
                SoftMode::Lut
            };
        }
        if let Some(r) = self.lut_resolution {
            desc.shadows.lut_resolution = r;
        }
        if self.no_clusters {
            desc.shadows.clusters = false;
        }
        if self.no_wedge_rule {
            desc.shadows.wedge_rule = false;
        }
        if self.frames > 1 && self.repeat > 1 {
            return Err(Error::InvalidInput(
                "--frames and --repeat do not go together: --repeat renders one frame again \
                 for its timings, --frames renders new ones and averages them"
                    .into(),
            ));
        }
        desc.validate()?;
        Ok(desc)
    }
}

/// `--frames N`: renders N frames of `desc` with fresh light samples
/// (`render` makes one, GPU or oracle), writes each frame's dump into
/// `DIR/frame-NNN` with `--dump DIR`, and returns the accumulated frame.
fn accumulate(
    args: &RenderArgs,
    desc: &SceneDescription,
    mut render: impl FnMut(&SceneDescription, u32) -> Result<Frame>,
) -> Result<Frame> {
    let mut acc = Accumulator::new();
    let mut last = None;
    let mut ms = 0.0;
    for f in 0..args.frames {
        if !args.quiet {
            eprintln!("frame {}/{}", f + 1, args.frames);
        }
        let frame = render(&acc.next_frame(desc), f)?;
        if let Some(dir) = &args.dump {
            frame
                .dump
                .write(&dir.join(format!("frame-{f:03}")), &frame.image)?;
        }
        ms += frame.stats.total_ms();
        acc.add(&frame);
        last = Some(frame);
    }
    let last = last.ok_or_else(|| Error::InvalidInput("--frames must be at least 1".into()))?;
    let normals = ShadingNormals::new(&desc.scene);
    if !args.quiet {
        eprintln!("{} frames accumulated in {ms:.1} ms", args.frames);
    }
    Ok(acc.frame(desc, &normals, &last))
}

/// Writes the image and the dump. The image goes under a temporary name
/// next to its own (`.partial.NAME`) and is renamed only once the dump is
/// written too, so that a failed run never leaves an image that looks
/// complete (the dump does the same with its files).
/// `-o` inside the `--dump` folder may be the dump's own `image.png` (the
/// same picture, written by both); it may not be another file of the dump.
fn check_output_paths(args: &RenderArgs) -> Result<()> {
    let (out, Some(dump)) = (&args.output, &args.dump) else {
        return Ok(());
    };
    let parent = out.parent().filter(|p| !p.as_os_str().is_empty());
    let parent = parent.unwrap_or(std::path::Path::new("."));
    let same_dir = match (std::path::absolute(parent), std::path::absolute(dump)) {
        (Ok(a), Ok(b)) => a.components().eq(b.components()),
        _ => false,
    };
    // --frames writes DIR/frame-NNN/: -o may not name or enter one.
    if args.frames > 1 {
        if let (Ok(o), Ok(d)) = (std::path::absolute(out), std::path::absolute(dump)) {
            let o: Vec<_> = o.components().collect();
            let d: Vec<_> = d.components().collect();
            if o.len() > d.len()
                && o[..d.len()] == d[..]
                && o[d.len()]
                    .as_os_str()
                    .to_string_lossy()
                    .starts_with("frame-")
            {
                return Err(Error::InvalidInput(format!(
                    "-o {} is inside --dump {}'s per-frame folders (frame-NNN, written by \
                     --frames): choose another name",
                    out.display(),
                    dump.display()
                )));
            }
        }
    }
    let name = out.file_name().map(|n| n.to_string_lossy().into_owned());
    match name {
        Some(n) if same_dir && n != "image.png" && Dump::is_file_name(&n) => {
            Err(Error::InvalidInput(format!(
                "-o {} would overwrite the dump's own {n} in --dump {}: choose another name \
             (the dump holds the image as image.png)",
                out.display(),
                dump.display()
            )))
        }
        _ => Ok(()),
    }
}

fn write_outputs(args: &RenderArgs, frame: &Frame) -> Result<()> {
    let out = &args.output;
    let name = out
        .file_name()
        .ok_or_else(|| Error::InvalidInput(format!("-o {}: not a file name", out.display())))?;
    if let Some(parent) = out.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent).map_err(|e| Error::io(parent, e))?;
    }
    // Not the dump's `.partial.` prefix: `-o DUMP/image.png` would share its
    // temporary name with the dump's own image.
    let mut tmp_name = std::ffi::OsString::from(".partial-output.");
    tmp_name.push(name);
    let tmp = out.with_file_name(tmp_name);
    let written = (|| {
        frame
            .image
            .save_with_format(&tmp, image::ImageFormat::Png)
            .map_err(|e| Error::Image(format!("{}: {e}", out.display())))?;
        if let Some(dir) = &args.dump {
            frame.dump.write(dir, &frame.image)?;
        }
        std::fs::rename(&tmp, out).map_err(|e| Error::io(out, e))
    })();
    if written.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    written
}

fn report(desc: &SceneDescription, frame: &Frame, args: &RenderArgs, warm_ms: &[f64]) {
    println!(
        "{}: {} triangles, {}x{} pixels, {} light(s)",
        desc.name,
        desc.scene.triangle_count(),
        desc.camera.width,
        desc.camera.height,
        desc.lights.len()
    );
    for (k, v) in frame.dump.visibility.iter().enumerate() {
        let covered: Vec<f32> = v.iter().filter(|p| p[3] > 0.5).map(|p| p[0]).collect();
        let shadowed = covered.iter().filter(|&&x| x < 1.0).count();
        println!(
            "  light {k}: {} samples, {:.1}% of view samples at least partly shadowed",
            desc.lights[k].light_samples().len(),
            100.0 * shadowed as f64 / covered.len().max(1) as f64
        );
    }
    println!(
        "  total {:.1} ms on {}",
        frame.stats.total_ms(),
        frame.stats.device()
    );
    if !warm_ms.is_empty() {
        // One frame varies by tens of percent on a shared CPU: the median
        // of the warm ones is the number to compare.
        let mut t = warm_ms.to_vec();
        t.sort_by(f64::total_cmp);
        println!(
            "  {} warm frames: median {:.1} ms, min {:.1}, max {:.1}",
            t.len(),
            t[t.len() / 2],
            t[0],
            t[t.len() - 1]
        );
    }
    println!("  wrote {}", args.output.display());
    if let Some(d) = &args.dump {
        println!("  wrote dump to {}", d.display());
    }
    if args.stats {
        println!(
            "{}",
            serde_json::to_string_pretty(&frame.stats).unwrap_or_default()
        );
    }
}

/// `afs bench`: the sweep, its CSV, plot and ratio table.
fn bench(args: &BenchArgs) -> Result<()> {
    let mut engine = Engine::new(&ContextOptions {
        device: args.device.clone(),
        ..Default::default()
    })?;
    let options = alias_free_shadows::bench::BenchOptions {
        out: args.out.clone(),
        size: args.size.unwrap_or(if args.quick { 32 } else { 256 }),
        quick: args.quick,
        scenes: args.scenes.clone().unwrap_or_else(|| {
            if args.quick {
                vec!["builtin:plane_sphere".into()]
            } else {
                alias_free_shadows::bench::default_scenes()
            }
        }),
        repeats: args.repeats.unwrap_or(if args.quick { 1 } else { 3 }),
        reference_samples: args
            .reference_samples
            .unwrap_or(if args.quick { 256 } else { 4096 }),
        progress: !args.quiet,
    };
    let t0 = std::time::Instant::now();
    let rows = alias_free_shadows::bench::run(&mut engine, &options)?;
    print!("{}", alias_free_shadows::bench::ratios(&rows));
    println!(
        "{} configurations in {:.1} s; wrote {}, {} and {}",
        rows.len(),
        t0.elapsed().as_secs_f64(),
        options.out.join("bench.csv").display(),
        options.out.join("bench.png").display(),
        options.out.join("bench-ratios.md").display()
    );
    Ok(())
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Render(args) => {
            let desc = args.scene()?;
            check_output_paths(&args)?;
            let mut engine = Engine::new(&ContextOptions {
                device: args.device.clone(),
                ..Default::default()
            })?;
            engine.set_table_cache(alias_free_shadows::gpu::plane_lut::table_cache::default_dir());
            let options = FrameOptions {
                progress: !args.quiet,
            };
            // The frames after the first (`--repeat`): the first pays for
            // pipeline compilation.
            let mut warm_ms = Vec::new();
            let frame = if args.frames > 1 {
                accumulate(&args, &desc, |d, f| engine.render_jittered(d, f, options))?
            } else {
                let mut frame = engine.render(&desc, options)?;
                for _ in 1..args.repeat {
                    frame = engine.render(&desc, options)?;
                    warm_ms.push(frame.stats.total_ms());
                }
                frame
            };
            write_outputs(&args, &frame)?;
            report(&desc, &frame, &args, &warm_ms);
        }
        Command::Reference(args) => {
            let desc = args.scene()?;
            check_output_paths(&args)?;
            let options = FrameOptions {
                progress: !args.quiet,
            };
            let frame = if args.frames > 1 {
                accumulate(&args, &desc, |d, _| render_reference(d, options))?
            } else {
                render_reference(&desc, options)?
            };
            write_outputs(&args, &frame)?;
            report(&desc, &frame, &args, &[]);
        }
        Command::Compare {
            dump_a,
            dump_b,
            json,
        } => {
            let a = Dump::read(&dump_a)?;
            let b = Dump::read(&dump_b)?;
            let rows = compare(&a, &b)?;
            if json {
                println!(
                    "{}",
                    serde_json::to_string_pretty(&rows).unwrap_or_default()
                );
            } else {
                println!("light  pixels  mean_abs      rmse          max_abs   >1 sample  coverage_mismatch");
                for r in rows {
                    println!(
                        "{:>5} {:>7}  {:<12.6e}  {:<12.6e}  {:<8.5} {:>9.4}%  {}",
                        r.light,
                        r.pixels,
                        r.mean_abs,
                        r.rmse,
                        r.max_abs,
                        100.0 * r.share_over_one_sample,
                        r.coverage_mismatch
                    );
                    if let Some(c) = &r.channels {
                        println!(
                            "       rgb rmse {:.6e} {:.6e} {:.6e}, max_abs {:.5} {:.5} {:.5}",
                            c.rmse[0],
                            c.rmse[1],
                            c.rmse[2],
                            c.max_abs[0],
                            c.max_abs[1],
                            c.max_abs[2]
                        );
                    }
                }
            }
        }
        Command::Bench(args) => bench(&args)?,
        Command::Info => {
            let devices = vulkan::list_devices()?;
            if devices.is_empty() {
                return Err(Error::Vulkan(
                    "no Vulkan device found (install mesa-vulkan-drivers for lavapipe)".into(),
                ));
            }
            for d in devices {
                println!("{d}");
            }
        }
        Command::Export {
            scene: spec,
            output,
        } => {
            let name = spec.strip_prefix("builtin:").unwrap_or(&spec);
            let b = scene::builtin::builtin(name)?;
            scene::gltf_write::write_glb(&b.scene, &output)?;
            println!(
                "wrote {} ({} triangles)",
                output.display(),
                b.scene.triangle_count()
            );
        }
    }
    Ok(())
}

fn main() -> ExitCode {
    env_logger::Builder::from_env(env_logger::Env::default().default_filter_or("warn")).init();
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
