//! Alpha-tested casters' tables on the GPU ([`crate::cpu::alpha`] makes
//! them; `shaders/alpha_common.glsl` reads them): the triangles' records,
//! the textures' headers and their alphas, uploaded with the frame's
//! triangles and kept across frames. A light's passes run the
//! alpha-tested casters in a round of their own
//! ([`crate::gpu::light_passes`]).

use crate::cpu::alpha::{AlphaTables, ALPHA_NONE};
use crate::gpu::dispatch::RGBA32UI;
use crate::gpu::shared::{GpuTriangle, TRIANGLE_ALPHA, TRIANGLE_INVISIBLE};
use crate::vulkan::{vk, Binding, BufferSlice, GpuContext, GrowBuffer};
use crate::Result;

/// The three tables the alpha tests read, bound as texel buffers.
#[derive(Clone, Copy)]
pub struct AlphaInputs<'a> {
    /// Two `RGBA32UI` texels per alpha-tested triangle.
    pub records: BufferSlice<'a>,
    /// Two `RGBA32UI` texels per texture.
    pub textures: BufferSlice<'a>,
    /// `R8UI` alphas.
    pub alphas: BufferSlice<'a>,
}

impl<'a> AlphaInputs<'a> {
    /// `none` (16 bytes, never read) bound in place of every table: a run
    /// without alpha-tested triangles still needs a descriptor.
    pub fn placeholder(none: BufferSlice<'a>) -> Self {
        AlphaInputs {
            records: none,
            textures: none,
            alphas: none,
        }
    }

    /// Their bindings, in the shaders' order (records, textures, alphas).
    pub fn bindings(&self) -> [Binding<'a>; 3] {
        [
            Binding::uniform_texel(self.records, RGBA32UI),
            Binding::uniform_texel(self.textures, RGBA32UI),
            Binding::uniform_texel(self.alphas, vk::Format::R8_UINT),
        ]
    }
}

/// The tables' buffers, and a small one bound in their place when a run
/// has no alpha-tested caster (a descriptor needs a buffer).
pub struct AlphaBuffers {
    records: GrowBuffer,
    textures: GrowBuffer,
    alphas: GrowBuffer,
    none: GrowBuffer,
    /// Whether the last upload had any alpha-tested triangle.
    present: bool,
}

impl AlphaBuffers {
    /// No buffers yet.
    pub fn new() -> Self {
        AlphaBuffers {
            records: GrowBuffer::storage("alpha_records"),
            textures: GrowBuffer::storage("alpha_textures"),
            alphas: GrowBuffer::storage("alpha_texels"),
            none: GrowBuffer::storage("alpha_none"),
            present: false,
        }
    }

    /// Uploads `tables` (nothing when they are empty).
    pub fn upload(&mut self, ctx: &GpuContext, tables: &AlphaTables) -> Result<()> {
        self.none.get(ctx, 16)?;
        self.present = !tables.is_empty();
        if !self.present {
            return Ok(());
        }
        let (records, textures, mut alphas) = tables.gpu();
        // Staged uploads move whole words.
        alphas.resize(alphas.len().next_multiple_of(4), 0);
        let b = self.records.get(ctx, 16 * records.len() as u64)?;
        ctx.upload_staged(b, 0, &records)?;
        let b = self.textures.get(ctx, 16 * textures.len() as u64)?;
        ctx.upload_staged(b, 0, &textures)?;
        let b = self.alphas.get(ctx, alphas.len() as u64)?;
        ctx.upload_staged(b, 0, &alphas)?;
        Ok(())
    }

    /// Whether the last upload had any alpha-tested triangle.
    pub fn present(&self) -> bool {
        self.present
    }

    /// The tables of the last upload; without any alpha-tested triangle, a
    /// small buffer in their place (a descriptor needs one).
    ///
    /// # Panics
    /// Before the first [`AlphaBuffers::upload`] (the shadow pipeline makes
    /// one when it is made).
    pub fn inputs(&self) -> AlphaInputs<'_> {
        if self.present {
            AlphaInputs {
                records: self.records.slice(),
                textures: self.textures.slice(),
                alphas: self.alphas.slice(),
            }
        } else {
            AlphaInputs::placeholder(self.none.slice())
        }
    }

    /// Bytes held on the device.
    pub fn bytes(&self) -> u64 {
        self.records.capacity() + self.textures.capacity() + self.alphas.capacity()
    }
}

impl Default for AlphaBuffers {
    fn default() -> Self {
        Self::new()
    }
}

/// Marks `triangles` (global ids, [`crate::scene::Scene::triangles`]
/// order) that `tables` alpha-tests: [`TRIANGLE_ALPHA`] and their record
/// (and [`TRIANGLE_INVISIBLE`] for those transparent everywhere).
pub fn mark_alpha_triangles(triangles: &mut [GpuTriangle], tables: &AlphaTables) {
    for (t, &r) in triangles.iter_mut().zip(&tables.triangle_records) {
        if r != ALPHA_NONE {
            t.flags |= TRIANGLE_ALPHA;
            if tables.records[r as usize].invisible {
                t.flags |= TRIANGLE_INVISIBLE;
            }
            t.alpha_record = r;
        }
    }
}
