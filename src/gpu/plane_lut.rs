//! The plane look-up texture (paper §4.2): for every plane of a grid over
//! (octahedral normal, distance) in the light's normalized frame, the bits
//! of the light samples behind it, one `[u32; 4]` per 128-sample block.
//! Approximate mode: the bits of the texel's own plane (shader
//! `plane_lut_build.comp`, one invocation per texel). Look-up mode: the
//! bits of the samples behind each plane of every normal cell's centre
//! normal, the planes of a cell side by side, from which each caster's
//! plane reads one plane below and one above it (with margins for its
//! normal's distance to the cell's centre and the exact test's rounding),
//! built on the host ([`crate::cpu::plane_lut::build_sure_lut`]) and
//! uploaded. It depends only
//! on the normalized samples and the resolution, so the last table built is
//! kept across frames and rebuilt only when those change. CPU twin:
//! [`crate::cpu::plane_lut`].

use crate::cpu::plane_lut::build_sure_lut_into;
use crate::gpu::dispatch::{groups, RGBA32UI};
use crate::gpu::pass_clock::PassClock;
use crate::gpu::shaders;
use crate::gpu::shared::LightPush;
use crate::gpu::soft_light::{SoftLight, SoftMode, MAX_SOFT_SAMPLES};
use crate::vulkan::{
    Barrier, Binding, Buffer, BufferDesc, ComputePipeline, ComputePipelineDesc, DescriptorKind,
    GpuContext, GrowBuffer,
};
use crate::{Error, Result};

/// The table's pipeline and the last table built.
pub struct PlaneLutPass {
    build: ComputePipeline,
    /// The last table and what it was built from.
    table: Option<PlaneLut>,
    /// The normalized samples the build reads (uniform buffer).
    normalized: GrowBuffer,
    /// Where look-up mode's tables are kept across runs (None: not kept).
    cache_dir: Option<std::path::PathBuf>,
    /// The thread writing the last table built into the cache, if any.
    writer: Option<std::thread::JoinHandle<()>>,
    /// Whether a cached table may be mapped ([`PlaneLutPass::map_cached`]).
    map_cached: bool,
}

impl Drop for PlaneLutPass {
    fn drop(&mut self) {
        self.finish_writing();
    }
}

/// A plane look-up texture on the device and what it was built from.
struct PlaneLut {
    /// Bits of the normalized samples, then the resolution.
    key: Vec<u32>,
    buffer: Buffer,
}

impl PlaneLutPass {
    /// Builds the pipeline.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        Ok(PlaneLutPass {
            build: ctx.create_compute_pipeline_deferred(&ComputePipelineDesc {
                name: "plane_lut_build",
                spirv: shaders::PLANE_LUT_BUILD,
                bindings: &[
                    DescriptorKind::StorageTexelBuffer,
                    DescriptorKind::UniformBuffer,
                ],
                push_constant_bytes: std::mem::size_of::<LightPush>() as u32,
                specialization: &[],
            })?,
            table: None,
            normalized: GrowBuffer::storage_uniform("normalized_light_samples"),
            cache_dir: None,
            writer: None,
            map_cached: true,
        })
    }

    /// Writes the table just built in `buffer` to the cache file `path` on
    /// a thread beside the frame: the disk's time is not the frame's
    /// (writing a 512 MiB table added 0.6 to 3 s to a frame here). The thread reads the
    /// buffer's mapped memory, which the GPU only reads and which stays
    /// until [`PlaneLutPass::finish_writing`] (called before the table is
    /// replaced or dropped); without a mapping it reads a host copy.
    fn start_writing(
        &mut self,
        ctx: &GpuContext,
        buffer: &Buffer,
        path: std::path::PathBuf,
        key: Vec<u32>,
    ) -> Result<()> {
        struct Table(*const u8, usize);
        // SAFETY: see below; the memory is only read.
        unsafe impl Send for Table {}
        let table = match buffer.mapped_range() {
            Some((p, n)) if (p as usize).is_multiple_of(std::mem::align_of::<[u32; 4]>()) => {
                Err(Table(p, n))
            }
            _ => match ctx.read_buffer_staged::<[u32; 4]>(buffer, 0, (buffer.size() / 16) as usize)
            {
                Ok(v) => Ok(v),
                Err(e) => {
                    log::warn!("{}: the look-up table is not kept: {e}", path.display());
                    return Ok(());
                }
            },
        };
        self.writer = Some(std::thread::spawn(move || {
            let lut: &[[u32; 4]] = match &table {
                Ok(v) => v,
                // SAFETY: the buffer outlives the thread (it is freed only
                // after finish_writing joined it: ensure, Drop), nothing
                // writes it meanwhile (the GPU reads the table; the pass
                // hands it out only inside the crate), and the mapping is
                // aligned for [u32; 4] (checked above), 16 bytes per texel.
                Err(Table(p, n)) => unsafe {
                    std::slice::from_raw_parts(*p as *const [u32; 4], *n / 16)
                },
            };
            table_cache::write(&path, &key, lut)
        }));
        Ok(())
    }

    /// Waits until the cache's writer, if any, has written its table.
    pub fn finish_writing(&mut self) {
        if let Some(w) = self.writer.take() {
            if w.join().is_err() {
                log::warn!("the look-up table's cache writer failed; the table is not kept");
            }
        }
    }

    /// Makes the table of `light` current: builds it (its own submission,
    /// timed as `lut_build`) unless the last one was built from the same
    /// normalized samples and resolution. Returns whether it was built.
    pub fn ensure(
        &mut self,
        ctx: &GpuContext,
        clock: &mut PassClock,
        light: &SoftLight,
    ) -> Result<bool> {
        let (centre, radius) = light.bounds();
        let ys = crate::cpu::plane_lut::normalized_samples(&light.samples, centre, radius);
        let mut key: Vec<u32> = ys
            .iter()
            .flat_map(|y| y.to_array().map(f32::to_bits))
            .collect();
        key.push(light.lut_resolution);
        let bounds = light.mode == SoftMode::Lut;
        // The kind: 0 approximate mode's table, 2 look-up mode's (1 was
        // its earlier layout, two masks per texel: such files are not read).
        key.push(if bounds { 2 } else { 0 });
        if self.table.as_ref().is_some_and(|l| l.key == key) {
            return Ok(false);
        }
        let res = light.lut_resolution as u64;
        // One mask per texel and block in both modes.
        let texels = res.pow(3) * light.blocks() as u64;
        let max_texels = ctx.info().limits.max_texel_buffer_elements as u64;
        if texels > max_texels {
            return Err(Error::InvalidInput(format!(
                "a {res}³ look-up texture for {} light samples has {texels} texels; this device binds at most {max_texels} (lower lut_resolution or the samples)",
                light.samples.len()
            )));
        }
        self.finish_writing(); // the writer reads the old table
        self.table = None; // the old table is freed before the new one is made
        let desc = BufferDesc::storage("plane_lut", 16 * texels);
        if bounds {
            // From the cache on disk: mapped as the buffer's memory where
            // the device allows it, else read straight into the buffer;
            // else built on the host in parallel, O(cells · samples) (see
            // build_sure_lut), into the buffer, and kept.
            let cache = self
                .cache_dir
                .as_deref()
                .map(|d| table_cache::path(d, &key));
            let cached = cache
                .as_deref()
                .and_then(|p| table_cache::open(p, &key, texels));
            if let Some(file) = &cached {
                if let Some(buffer) = self.map_cached(ctx, clock, file, &desc)? {
                    self.table = Some(PlaneLut { key, buffer });
                    return Ok(true);
                }
            }
            let buffer = ctx.create_buffer(desc)?;
            let name = if cached.is_some() {
                "lut_read"
            } else {
                "lut_build"
            };
            let built = clock.time_host(name, || {
                ctx.upload_with(&buffer, |lut: &mut [[u32; 4]]| {
                    if let Some(file) = cached {
                        if file.read_into(bytemuck::cast_slice_mut(lut)) {
                            return Ok(false);
                        }
                    }
                    build_sure_lut_into(&ys, light.lut_resolution, lut);
                    Ok(true)
                })
            })?;
            if let (true, Some(p)) = (built, cache) {
                self.start_writing(ctx, &buffer, p, key.clone())?;
            }
            self.table = Some(PlaneLut { key, buffer });
            return Ok(true);
        }
        let buffer = ctx.create_buffer(desc)?;
        let v: Vec<[f32; 4]> = ys.iter().map(|y| [y.x, y.y, y.z, 0.0]).collect();
        let ys_ubo = self.normalized.get(ctx, 16 * MAX_SOFT_SAMPLES as u64)?;
        ctx.upload_staged(ys_ubo, 0, &v)?;
        let push = LightPush {
            soft: [0, light.samples.len() as u32, light.lut_resolution, 0],
            ..Default::default()
        };
        let mut rec = ctx.begin()?;
        let normalized = &self.normalized;
        clock.time(ctx, &mut rec, "lut_build", |rec| {
            rec.dispatch(
                &self.build,
                &[
                    Binding::storage_texel(&buffer, RGBA32UI),
                    Binding::uniform(normalized),
                ],
                bytemuck::bytes_of(&push),
                groups(res.pow(3) as u32),
            )?;
            rec.barrier(Barrier::ComputeToHost);
            Ok(())
        })?;
        ctx.submit_and_wait(rec)?;
        ctx.check_validation()?;
        self.table = Some(PlaneLut { key, buffer });
        Ok(true)
    }

    /// The cached table `file` as a buffer whose memory is the file's
    /// pages (timed as `lut_mapped`): on a CPU device with
    /// `VK_EXT_external_memory_host`, whose device memory is host memory
    /// anyway, so that a 512 MiB table costs no copy and no fresh pages
    /// (reading it into a new buffer took 0.38 s here, mostly the kernel
    /// zeroing and mapping the buffer's pages). None elsewhere (a GPU
    /// would read host memory over the bus at every look-up), when
    /// mapping is off, or when mapping or importing fails (a warning).
    fn map_cached(
        &self,
        ctx: &GpuContext,
        clock: &mut PassClock,
        file: &table_cache::CachedTable,
        desc: &BufferDesc,
    ) -> Result<Option<Buffer>> {
        let info = ctx.info();
        let align = info.min_imported_host_pointer_alignment;
        if !self.map_cached
            || !info.is_cpu()
            || !info.features.external_memory_host
            || align == 0
            || !table_cache::DATA_ALIGN.is_multiple_of(align)
        {
            return Ok(None);
        }
        clock.time_host("lut_mapped", || {
            let Some(mapped) = file.map() else {
                return Ok(None);
            };
            let (ptr, len) = (mapped.ptr(), mapped.len() as u64);
            // SAFETY: the extension is enabled (features), the mapping is
            // page-aligned and a multiple of DATA_ALIGN long (so of the
            // alignment, checked above), it lives as long as the buffer
            // (its owner), its contents never change (see MappedTable),
            // and the GPU only reads the table.
            match unsafe {
                Buffer::from_host_memory(ctx.device(), desc, ptr, len, Box::new(mapped))
            } {
                Ok(b) => Ok(Some(b)),
                Err(e) => {
                    log::warn!("the cached look-up table cannot be mapped ({e}); reading it");
                    Ok(None)
                }
            }
        })
    }

    /// Maps tables read from the cache into device memory where the device
    /// allows it (on by default; off reads them, as on a GPU: for tests of
    /// that path and for measuring).
    pub fn set_cache_mapping(&mut self, on: bool) {
        self.map_cached = on;
    }

    /// Keeps look-up mode's tables in `dir` across runs (None: never).
    pub fn set_cache_dir(&mut self, dir: Option<std::path::PathBuf>) {
        self.cache_dir = dir;
    }

    /// Where tables are kept, taken out (none kept until it is set again).
    pub fn take_cache_dir(&mut self) -> Option<std::path::PathBuf> {
        self.cache_dir.take()
    }

    /// The current table (after [`PlaneLutPass::ensure`]). Crate-only: the
    /// cache's writer may be reading it.
    pub(crate) fn table(&self) -> Option<&Buffer> {
        self.table.as_ref().map(|t| &t.buffer)
    }

    /// The table of `light` as the GPU builds it (for the CPU twin's test):
    /// per texel, then per 128-sample block, the bits of the samples behind
    /// the texel's plane ([`crate::cpu::plane_lut::build_lut`]).
    pub fn bits(
        &mut self,
        ctx: &GpuContext,
        clock: &mut PassClock,
        light: &SoftLight,
    ) -> Result<Vec<[u32; 4]>> {
        clock.restart(ctx);
        self.ensure(ctx, clock, light)?;
        let lut = self.table().expect("ensure keeps a table");
        let words: Vec<u32> = ctx.read_buffer_staged(lut, 0, (lut.size() / 4) as usize)?;
        Ok(words
            .chunks_exact(4)
            .map(|w| [w[0], w[1], w[2], w[3]])
            .collect())
    }
}

/// Look-up mode's tables on disk, keyed by what they are built from (the
/// normalized samples' bits, the resolution, the kind): a file per table,
/// named by a hash of the key and holding the whole key, so a file is used
/// only for exactly its key. At most [`table_cache::KEPT`] files stay (the
/// oldest go); any failure to read or write is a warning, never an error
/// (the table is then built).
pub mod table_cache {
    use std::path::{Path, PathBuf};

    /// Files kept in the directory.
    pub const KEPT: usize = 8;
    const MAGIC: &[u8; 8] = b"AFSLUT03";
    /// Bytes per read or write call: one call of a whole 512 MiB table
    /// took 4.4 s to write here, 4 MiB calls 0.11 s (`dd` shows the same).
    const CHUNK: usize = 4 << 20;
    /// The texels start at a multiple of this in the file, and the file
    /// ends at one (zeros after the header and after the texels), so that
    /// they can be mapped and imported as device memory
    /// ([`CachedTable::map`]): a multiple of every page size and of
    /// lavapipe's `minImportedHostPointerAlignment` (4 KiB).
    pub const DATA_ALIGN: u64 = 64 << 10;

    fn align_up(n: u64) -> u64 {
        n.div_ceil(DATA_ALIGN) * DATA_ALIGN
    }

    /// The directory tables go to by default: `AFS_TABLE_CACHE` (`0` or
    /// `off`: none), else `$XDG_CACHE_HOME/alias-free-shadows`, else
    /// `$HOME/.cache/alias-free-shadows`.
    pub fn default_dir() -> Option<PathBuf> {
        match std::env::var("AFS_TABLE_CACHE") {
            Ok(v) if v == "0" || v == "off" => return None,
            Ok(v) if !v.is_empty() => return Some(PathBuf::from(v)),
            _ => {}
        }
        let base = std::env::var_os("XDG_CACHE_HOME")
            .map(PathBuf::from)
            .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))?;
        Some(base.join("alias-free-shadows"))
    }

    /// FNV-1a over the key's words.
    fn hash(key: &[u32]) -> u64 {
        key.iter()
            .flat_map(|w| w.to_le_bytes())
            .fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
                (h ^ b as u64).wrapping_mul(0x100_0000_01b3)
            })
    }

    /// The file of the table of `key` in `dir`.
    pub fn path(dir: &Path, key: &[u32]) -> PathBuf {
        dir.join(format!("plane-lut-{:016x}.bin", hash(key)))
    }

    /// The header's bytes: magic, key length, key.
    fn header(key: &[u32]) -> Vec<u8> {
        let mut head = Vec::with_capacity(12 + 4 * key.len());
        head.extend_from_slice(MAGIC);
        head.extend_from_slice(&(key.len() as u32).to_le_bytes());
        for k in key {
            head.extend_from_slice(&k.to_le_bytes());
        }
        head
    }

    /// A table file whose header holds `key` and whose size fits `texels`
    /// texels.
    pub struct CachedTable {
        file: std::fs::File,
        path: PathBuf,
        /// Where the texels start.
        offset: u64,
        /// The texels' bytes.
        bytes: u64,
    }

    /// The table file of `key` in `path`, if its header holds `key` and its
    /// size fits `texels` texels (a file of another key or size: a warning,
    /// and None).
    pub fn open(path: &Path, key: &[u32], texels: u64) -> Option<CachedTable> {
        use std::io::Read;
        let mut file = std::fs::File::open(path).ok()?;
        let want = header(key);
        let mut head = vec![0u8; want.len()];
        let offset = align_up(want.len() as u64);
        let bytes = 16 * texels;
        let ok = file.read_exact(&mut head).is_ok()
            && file.metadata().ok()?.len() == offset + align_up(bytes)
            && head == want;
        if !ok {
            log::warn!("{}: not the table wanted; building it", path.display());
            return None;
        }
        Some(CachedTable {
            file,
            path: path.to_owned(),
            offset,
            bytes,
        })
    }

    impl CachedTable {
        /// Reads the texels into `out` (exactly their size); false (with a
        /// warning) when the file ends early or cannot be read.
        pub fn read_into(mut self, out: &mut [u8]) -> bool {
            use std::io::{Read, Seek};
            let read = self
                .file
                .seek(std::io::SeekFrom::Start(self.offset))
                .and_then(|_| {
                    out.chunks_mut(CHUNK)
                        .try_for_each(|c| self.file.read_exact(c))
                });
            match read {
                Ok(()) => true,
                Err(e) => {
                    log::warn!("{}: {e}; building the table", self.path.display());
                    false
                }
            }
        }

        /// The texels mapped read-only into memory, with every page of the
        /// mapping filled in now (`MAP_POPULATE`: what a read would touch,
        /// at no copy), followed by zeros up to a multiple of
        /// [`DATA_ALIGN`]; None (with a warning) where mapping fails or
        /// the platform has no `mmap`.
        pub fn map(&self) -> Option<MappedTable> {
            #[cfg(unix)]
            {
                use std::os::fd::AsRawFd;
                let len = align_up(self.bytes) as usize;
                // SAFETY: a fresh read-only shared mapping of an open file
                // at a page-aligned offset; nothing else aliases it.
                let ptr = unsafe {
                    libc::mmap(
                        std::ptr::null_mut(),
                        len,
                        libc::PROT_READ,
                        libc::MAP_SHARED | libc::MAP_POPULATE,
                        self.file.as_raw_fd(),
                        self.offset as libc::off_t,
                    )
                };
                if ptr == libc::MAP_FAILED {
                    log::warn!(
                        "{}: mapping failed ({}); reading it",
                        self.path.display(),
                        std::io::Error::last_os_error()
                    );
                    return None;
                }
                Some(MappedTable { ptr, len })
            }
            #[cfg(not(unix))]
            None
        }
    }

    /// A table file's texels mapped into memory, unmapped on drop. The
    /// cache writes a table's file under another name and renames it, and
    /// removes old ones, so a mapped file's contents never change; a file
    /// another program truncates meanwhile would fault its readers.
    pub struct MappedTable {
        ptr: *mut std::ffi::c_void,
        len: usize,
    }

    // SAFETY: the mapping is read-only and owned by this value alone.
    unsafe impl Send for MappedTable {}
    unsafe impl Sync for MappedTable {}

    impl MappedTable {
        /// The start of the mapping (page-aligned).
        pub fn ptr(&self) -> *mut std::ffi::c_void {
            self.ptr
        }

        /// Its length in bytes (a multiple of [`DATA_ALIGN`]).
        pub fn len(&self) -> usize {
            self.len
        }

        /// Whether it maps nothing (never: tables have texels).
        pub fn is_empty(&self) -> bool {
            self.len == 0
        }
    }

    impl Drop for MappedTable {
        fn drop(&mut self) {
            #[cfg(unix)]
            // SAFETY: the mapping made in CachedTable::map, unmapped once.
            unsafe {
                libc::munmap(self.ptr, self.len);
            }
        }
    }

    /// Writes the table of `key` to `path` (under a temporary name, then
    /// renamed) and removes the oldest files past [`KEPT`].
    pub fn write(path: &Path, key: &[u32], lut: &[[u32; 4]]) {
        let written = (|| -> std::io::Result<()> {
            let dir = path.parent().unwrap_or(Path::new("."));
            std::fs::create_dir_all(dir)?;
            use std::io::Write;
            let mut head = header(key);
            head.resize(align_up(head.len() as u64) as usize, 0);
            // Unique per writer, so two engines of one process writing the
            // same table never share a temporary file.
            static WRITES: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
            let n = WRITES.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            let tmp = path.with_extension(format!("partial.{}.{n}", std::process::id()));
            let mut file = std::fs::File::create(&tmp)?;
            file.write_all(&head)?;
            let texels: &[u8] = bytemuck::cast_slice(lut);
            for c in texels.chunks(CHUNK) {
                file.write_all(c)?;
            }
            let end = align_up(texels.len() as u64) - texels.len() as u64;
            file.write_all(&vec![0u8; end as usize])?;
            drop(file);
            std::fs::rename(&tmp, path)?;
            let mut files: Vec<(std::time::SystemTime, PathBuf)> = std::fs::read_dir(dir)?
                .flatten()
                .filter(|e| {
                    let n = e.file_name();
                    let n = n.to_string_lossy();
                    n.starts_with("plane-lut-") && n.ends_with(".bin")
                })
                .filter_map(|e| Some((e.metadata().ok()?.modified().ok()?, e.path())))
                .collect();
            files.sort();
            let extra = files.len().saturating_sub(KEPT);
            for (_, old) in files.into_iter().take(extra) {
                let _ = std::fs::remove_file(old);
            }
            Ok(())
        })();
        if let Err(e) = written {
            log::warn!("{}: the look-up table is not kept: {e}", path.display());
        }
    }
}
