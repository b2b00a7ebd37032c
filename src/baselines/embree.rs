//! Embree 3 (Intel's CPU ray tracer; Debian's `libembree-dev`, 3.13) as the
//! yardstick a user would otherwise pick: the same view samples and light
//! samples as the engine, one occlusion ray per (view sample, light sample)
//! pair that the normal rule leaves, on this machine's CPU with a chosen
//! number of threads. Built with the cargo feature `embree`; a thin FFI of
//! our own (the few calls it needs, checked against Embree 3.13's headers).
//!
//! Embree works in `f32`: the scene and the rays are camera-relative, as the
//! engine's. A ray starts `offset` from its view sample (a ray-origin
//! offset, in scene units, so that it does not hit the sample's own surface)
//! and ends `offset` short of its light sample; with the oracle's normal
//! rule (a light sample behind the surface is not visible, no ray). So
//! Embree agrees with the oracle except near contacts: where a blocker lies
//! within `offset` of the view sample (see `tests/embree.rs`).

use std::ffi::{c_char, c_void, CString};
use std::time::Instant;

use glam::Vec3;
use rayon::prelude::*;

use crate::{Error, Result};

#[allow(non_camel_case_types, dead_code)]
mod ffi {
    use std::ffi::{c_char, c_int, c_uint, c_void};

    pub type RTCDevice = *mut c_void;
    pub type RTCScene = *mut c_void;
    pub type RTCGeometry = *mut c_void;

    pub const RTC_GEOMETRY_TYPE_TRIANGLE: c_uint = 0;
    pub const RTC_BUFFER_TYPE_INDEX: c_uint = 0;
    pub const RTC_BUFFER_TYPE_VERTEX: c_uint = 1;
    pub const RTC_FORMAT_UINT3: c_uint = 0x5003;
    pub const RTC_FORMAT_FLOAT3: c_uint = 0x9003;
    pub const RTC_BUILD_QUALITY_HIGH: c_uint = 2;
    pub const RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT: c_uint = 0;
    pub const RTC_INTERSECT_CONTEXT_FLAG_COHERENT: c_uint = 1;
    pub const RTC_INVALID_GEOMETRY_ID: c_uint = u32::MAX;

    /// `RTCIntersectContext` with `RTC_MAX_INSTANCE_LEVEL_COUNT` = 1 and
    /// `RTC_MIN_WIDTH` = 0 (Embree 3.13's `rtcore_config.h`).
    #[repr(C)]
    pub struct RTCIntersectContext {
        pub flags: c_uint,
        pub filter: *const c_void,
        pub inst_id: [c_uint; 1],
    }

    /// `RTCRay`.
    #[repr(C, align(16))]
    #[derive(Clone, Copy, Default)]
    pub struct RTCRay {
        pub org: [f32; 3],
        pub tnear: f32,
        pub dir: [f32; 3],
        pub time: f32,
        pub tfar: f32,
        pub mask: c_uint,
        pub id: c_uint,
        pub flags: c_uint,
    }

    /// `RTCRay8`: eight rays, structure of arrays.
    #[repr(C, align(32))]
    #[derive(Clone, Copy, Default)]
    pub struct RTCRay8 {
        pub org_x: [f32; 8],
        pub org_y: [f32; 8],
        pub org_z: [f32; 8],
        pub tnear: [f32; 8],
        pub dir_x: [f32; 8],
        pub dir_y: [f32; 8],
        pub dir_z: [f32; 8],
        pub time: [f32; 8],
        pub tfar: [f32; 8],
        pub mask: [c_uint; 8],
        pub id: [c_uint; 8],
        pub flags: [c_uint; 8],
    }

    #[link(name = "embree3")]
    extern "C" {
        pub fn rtcNewDevice(config: *const c_char) -> RTCDevice;
        pub fn rtcReleaseDevice(device: RTCDevice);
        pub fn rtcGetDeviceError(device: RTCDevice) -> c_uint;
        pub fn rtcNewScene(device: RTCDevice) -> RTCScene;
        pub fn rtcReleaseScene(scene: RTCScene);
        pub fn rtcSetSceneBuildQuality(scene: RTCScene, quality: c_uint);
        pub fn rtcAttachGeometry(scene: RTCScene, geometry: RTCGeometry) -> c_uint;
        pub fn rtcCommitScene(scene: RTCScene);
        pub fn rtcNewGeometry(device: RTCDevice, kind: c_uint) -> RTCGeometry;
        pub fn rtcReleaseGeometry(geometry: RTCGeometry);
        pub fn rtcCommitGeometry(geometry: RTCGeometry);
        pub fn rtcSetNewGeometryBuffer(
            geometry: RTCGeometry,
            kind: c_uint,
            slot: c_uint,
            format: c_uint,
            byte_stride: usize,
            item_count: usize,
        ) -> *mut c_void;
        pub fn rtcOccluded1(scene: RTCScene, context: *mut RTCIntersectContext, ray: *mut RTCRay);
        pub fn rtcOccluded8(
            valid: *const c_int,
            scene: RTCScene,
            context: *mut RTCIntersectContext,
            ray: *mut RTCRay8,
        );
    }
}

/// How the rays go to Embree.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RayMode {
    /// `rtcOccluded1`, one ray at a time (incoherent context).
    Single,
    /// `rtcOccluded8`: packets of eight rays from one view sample (coherent
    /// context): Embree's advice for coherent rays.
    Packets8,
}

/// A triangle scene committed to Embree (its own device, `threads` build
/// threads).
pub struct EmbreeScene {
    device: ffi::RTCDevice,
    scene: ffi::RTCScene,
    /// Milliseconds the BVH build took.
    pub build_ms: f64,
    /// The ray-origin offset [`light_shadows`] uses.
    pub offset: f32,
}

// Embree scenes are safe to query from many threads once committed.
unsafe impl Send for EmbreeScene {}
unsafe impl Sync for EmbreeScene {}

impl EmbreeScene {
    /// Commits `triangles` (camera-relative `f32`) to a new device with
    /// `threads` threads and a high-quality BVH.
    pub fn new(triangles: &[[Vec3; 3]], threads: usize) -> Result<Self> {
        let config = CString::new(format!("threads={threads}")).expect("no NUL");
        let device = unsafe { ffi::rtcNewDevice(config.as_ptr() as *const c_char) };
        if device.is_null() {
            return Err(Error::InvalidInput(
                "Embree: rtcNewDevice failed (is libembree3 installed?)".into(),
            ));
        }
        let t0 = Instant::now();
        let scene = unsafe { ffi::rtcNewScene(device) };
        let mut out = EmbreeScene {
            device,
            scene,
            build_ms: 0.0,
            offset: 1e-5,
        };
        if !triangles.is_empty() {
            out.add_triangles(triangles)?;
        }
        unsafe {
            ffi::rtcSetSceneBuildQuality(scene, ffi::RTC_BUILD_QUALITY_HIGH);
            ffi::rtcCommitScene(scene);
        }
        out.check("rtcCommitScene")?;
        out.build_ms = t0.elapsed().as_secs_f64() * 1e3;
        Ok(out)
    }

    fn add_triangles(&mut self, triangles: &[[Vec3; 3]]) -> Result<()> {
        let n = triangles.len();
        unsafe {
            let geom = ffi::rtcNewGeometry(self.device, ffi::RTC_GEOMETRY_TYPE_TRIANGLE);
            let v = ffi::rtcSetNewGeometryBuffer(
                geom,
                ffi::RTC_BUFFER_TYPE_VERTEX,
                0,
                ffi::RTC_FORMAT_FLOAT3,
                12,
                3 * n,
            ) as *mut f32;
            let i = ffi::rtcSetNewGeometryBuffer(
                geom,
                ffi::RTC_BUFFER_TYPE_INDEX,
                0,
                ffi::RTC_FORMAT_UINT3,
                12,
                n,
            ) as *mut u32;
            if v.is_null() || i.is_null() {
                ffi::rtcReleaseGeometry(geom);
                return Err(Error::InvalidInput(format!(
                    "Embree: no buffers for {n} triangles"
                )));
            }
            let vs = std::slice::from_raw_parts_mut(v, 9 * n);
            let is = std::slice::from_raw_parts_mut(i, 3 * n);
            for (k, t) in triangles.iter().enumerate() {
                for (c, p) in t.iter().enumerate() {
                    vs[9 * k + 3 * c..9 * k + 3 * c + 3].copy_from_slice(&p.to_array());
                    is[3 * k + c] = (3 * k + c) as u32;
                }
            }
            ffi::rtcCommitGeometry(geom);
            ffi::rtcAttachGeometry(self.scene, geom);
            ffi::rtcReleaseGeometry(geom);
        }
        self.check("rtcCommitGeometry")
    }

    fn check(&self, what: &str) -> Result<()> {
        match unsafe { ffi::rtcGetDeviceError(self.device) } {
            0 => Ok(()),
            e => Err(Error::InvalidInput(format!("Embree: {what}: error {e}"))),
        }
    }

    /// Whether the segment from `origin + offset·d̂` to `origin + d − offset·d̂`
    /// (d̂ = d / |d|) meets a triangle.
    pub fn occluded(&self, origin: Vec3, d: Vec3, offset: f32) -> bool {
        let len = d.length();
        let mut ray = ffi::RTCRay {
            org: origin.to_array(),
            tnear: offset / len,
            dir: d.to_array(),
            tfar: 1.0 - offset / len,
            mask: u32::MAX,
            ..Default::default()
        };
        let mut ctx = context(ffi::RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT);
        unsafe { ffi::rtcOccluded1(self.scene, &mut ctx, &mut ray) };
        ray.tfar == f32::NEG_INFINITY
    }

    /// Up to eight segments from `origin` to `origin + d[k]` (as
    /// [`EmbreeScene::occluded`]) in one packet: bit k set when ray k is
    /// occluded.
    fn occluded8(&self, origin: Vec3, d: &[Vec3], offset: f32) -> u32 {
        let mut ray = ffi::RTCRay8::default();
        let mut valid = [0i32; 8];
        for (k, d) in d.iter().enumerate().take(8) {
            let len = d.length();
            valid[k] = -1;
            ray.org_x[k] = origin.x;
            ray.org_y[k] = origin.y;
            ray.org_z[k] = origin.z;
            ray.tnear[k] = offset / len;
            ray.dir_x[k] = d.x;
            ray.dir_y[k] = d.y;
            ray.dir_z[k] = d.z;
            ray.tfar[k] = 1.0 - offset / len;
            ray.mask[k] = u32::MAX;
        }
        let mut ctx = context(ffi::RTC_INTERSECT_CONTEXT_FLAG_COHERENT);
        unsafe { ffi::rtcOccluded8(valid.as_ptr(), self.scene, &mut ctx, &mut ray) };
        (0..d.len().min(8))
            .filter(|&k| ray.tfar[k] == f32::NEG_INFINITY)
            .fold(0, |m, k| m | 1 << k)
    }
}

fn context(flags: u32) -> ffi::RTCIntersectContext {
    ffi::RTCIntersectContext {
        flags,
        filter: std::ptr::null::<c_void>(),
        inst_id: [ffi::RTC_INVALID_GEOMETRY_ID],
    }
}

impl Drop for EmbreeScene {
    fn drop(&mut self) {
        unsafe {
            ffi::rtcReleaseScene(self.scene);
            ffi::rtcReleaseDevice(self.device);
        }
    }
}

/// What one run of shadow rays gives.
#[derive(Clone, Debug)]
pub struct EmbreeShadows {
    /// Per view sample: the visible share of the light samples (`None`
    /// where there is no view sample).
    pub visibility: Vec<Option<f32>>,
    /// Per view sample, its visible light samples: `mask_words` words, bit
    /// `j % 32` of word `j / 32` for light sample `j`.
    pub visible: Vec<u32>,
    /// Words per view sample in `visible` (a whole number of 32-sample
    /// words covering the light's samples).
    pub mask_words: usize,
    /// Rays cast (pairs the normal rule leaves).
    pub rays: u64,
    /// Wall milliseconds of casting them (the BVH build not included).
    pub ms: f64,
    /// Threads that cast them.
    pub threads: usize,
}

impl EmbreeShadows {
    /// Rays per second.
    pub fn rays_per_second(&self) -> f64 {
        self.rays as f64 / (self.ms * 1e-3).max(1e-12)
    }
}

/// Shadow rays from every view sample (camera-relative position, unit
/// normal) to every light sample (camera-relative), on `threads` threads:
/// a light sample is visible when it lies in front of the surface
/// (`dot(normal, l − p) > 0`) and its ray is not occluded.
pub fn shadow_rays(
    scene: &EmbreeScene,
    samples: &[Option<(Vec3, Vec3)>],
    light_samples: &[Vec3],
    offset: f32,
    threads: usize,
    mode: RayMode,
) -> Result<EmbreeShadows> {
    // 4 words per 128-sample block, as the engine's masks.
    let words = 4 * light_samples.len().div_ceil(128).max(1);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| Error::InvalidInput(format!("thread pool: {e}")))?;
    let mut visible = vec![0u32; words * samples.len()];
    let t0 = Instant::now();
    let rays: u64 = pool.install(|| {
        visible
            .par_chunks_mut(words * 64)
            .zip(samples.par_chunks(64))
            .map(|(masks, samples)| {
                let mut rays = 0u64;
                let mut dirs = Vec::with_capacity(light_samples.len());
                let mut ids = Vec::with_capacity(light_samples.len());
                for (mask, s) in masks.chunks_mut(words).zip(samples) {
                    let Some((p, n)) = *s else { continue };
                    dirs.clear();
                    ids.clear();
                    for (j, &l) in light_samples.iter().enumerate() {
                        let d = l - p;
                        if n.dot(d) > 0.0 {
                            dirs.push(d);
                            ids.push(j);
                        }
                    }
                    rays += dirs.len() as u64;
                    match mode {
                        RayMode::Single => {
                            for (d, &j) in dirs.iter().zip(&ids) {
                                if !scene.occluded(p, *d, offset) {
                                    mask[j / 32] |= 1 << (j % 32);
                                }
                            }
                        }
                        RayMode::Packets8 => {
                            for (d8, j8) in dirs.chunks(8).zip(ids.chunks(8)) {
                                let hit = scene.occluded8(p, d8, offset);
                                for (k, &j) in j8.iter().enumerate() {
                                    if hit >> k & 1 == 0 {
                                        mask[j / 32] |= 1 << (j % 32);
                                    }
                                }
                            }
                        }
                    }
                }
                rays
            })
            .sum()
    });
    let ms = t0.elapsed().as_secs_f64() * 1e3;
    let count = light_samples.len().max(1) as f32;
    let visibility = samples
        .iter()
        .enumerate()
        .map(|(i, s)| {
            s.map(|_| {
                let bits: u32 = visible[i * words..(i + 1) * words]
                    .iter()
                    .map(|w| w.count_ones())
                    .sum();
                bits as f32 / count
            })
        })
        .collect();
    Ok(EmbreeShadows {
        visibility,
        visible,
        mask_words: words,
        rays,
        ms,
        threads,
    })
}

/// The default ray-origin offset of a scene of bounding diagonal `diagonal`:
/// 1e-5 of it, at least 1e-6 of `scale` (the largest coordinate magnitude,
/// so that the offset stays above the coordinates' f32 rounding).
pub fn default_offset(diagonal: f32, scale: f32) -> f32 {
    (1e-5 * diagonal).max(1e-6 * scale)
}

/// [`shadow_rays`] for the engine's inputs: `scene` (committed once, see
/// [`EmbreeScene::from_scene`]), world-space view samples made relative to
/// `eye` as the engine makes them, and a point light or a light with
/// extent (every one of its [`Light::light_samples`](crate::light::Light::light_samples)).
pub fn light_shadows(
    embree: &EmbreeScene,
    scene: &crate::scene::Scene,
    eye: glam::DVec3,
    samples: &[Option<crate::oracle::ViewSample>],
    light: &crate::light::Light,
    threads: usize,
    mode: RayMode,
) -> Result<EmbreeShadows> {
    crate::render::validate_shadow_inputs(scene, eye, samples, light)?;
    let targets = match light.light_samples() {
        crate::light::LightSamples::Positions(p) => p,
        crate::light::LightSamples::Direction(_) => {
            return Err(Error::InvalidInput(
                "the Embree baseline takes lights with positions, not a direction".into(),
            ))
        }
    };
    let rel: Vec<Option<(Vec3, Vec3)>> = samples
        .iter()
        .map(|s| {
            s.map(|s| {
                (
                    (s.position - eye).as_vec3(),
                    s.normal.as_vec3().normalize_or_zero(),
                )
            })
        })
        .collect();
    let lights: Vec<Vec3> = targets.iter().map(|l| (*l - eye).as_vec3()).collect();
    shadow_rays(embree, &rel, &lights, embree.offset, threads, mode)
}

impl EmbreeScene {
    /// The scene's triangles, relative to `eye` (what the engine gets), with
    /// the scene's [`default_offset`].
    pub fn from_scene(
        scene: &crate::scene::Scene,
        eye: glam::DVec3,
        threads: usize,
    ) -> Result<Self> {
        let tris: Vec<[Vec3; 3]> = scene
            .triangles()
            .iter()
            .map(|t| t.vertices.map(|v| (v - eye).as_vec3()))
            .collect();
        let mut out = EmbreeScene::new(&tris, threads)?;
        if let Some((lo, hi)) = scene.bounds() {
            let scale = (lo - eye).abs().max((hi - eye).abs()).max_element() as f32;
            out.offset = default_offset((hi - lo).length() as f32, scale);
        }
        Ok(out)
    }
}
