//! What one run of a light's passes works on: its inputs on the GPU
//! ([`LightInputs`]), the sizes and push constants every pass shares
//! ([`LightFrame`]) and the recording the passes record into
//! ([`Recording`]).

use crate::cpu::light_view::LightView;
use crate::cpu::plane_lut::LUT_ALLOWANCE_CAP;
use crate::gpu::alpha::AlphaInputs;
use crate::gpu::pass_clock::PassClock;
use crate::gpu::shared::{LightPush, LIGHT_KIND_DIRECTIONAL, LIGHT_KIND_POINT};
use crate::gpu::soft_light::{SoftLight, SoftMode};
use crate::vulkan::{BufferSlice, CommandRecorder, GpuContext};
use crate::Result;

/// [`LightFrame::units`] of a caller's recording: the occlusion passes
/// take the count from the GPU (`min(more.w, unit_offsets[tiles])` in the
/// shaders) and dispatch indirectly.
pub const UNITS_INDIRECT: u32 = u32::MAX;

/// Tile side in texels (`TILE` in `shadow_common.glsl`).
pub const TILE: u32 = 8;

/// A run's view samples and triangles, already on the GPU.
#[derive(Clone, Copy)]
pub struct LightInputs<'a> {
    /// `n` [`GpuViewSample`](crate::gpu::shared::GpuViewSample)s (32 B each).
    pub samples: BufferSlice<'a>,
    /// Number of view samples in `samples` (invalid ones included).
    pub n: u32,
    /// `nt` [`GpuTriangle`](crate::gpu::shared::GpuTriangle)s (48 B each).
    pub triangles: BufferSlice<'a>,
    /// Number of triangles in `triangles` (this batch's).
    pub nt: u32,
    /// The global id of triangle 0 (triangle batches): view samples name
    /// their own triangle by global id.
    pub triangle_base: u32,
    /// The alpha-tested casters' tables (a placeholder without any).
    pub alpha: AlphaInputs<'a>,
    /// Whether some triangle is alpha-tested (`TRIANGLE_ALPHA`): then the
    /// opaque casters and the alpha-tested ones run in rounds of their own.
    pub alpha_casters: bool,
}

/// The sizes of one run and the push constants of its passes.
#[derive(Clone, Copy, Debug)]
pub struct LightFrame {
    /// Light faces (6 for a point light's cube, 1 for a directional light).
    pub faces: u32,
    /// Light texels per face side.
    pub resolution: u32,
    /// Tiles of [`TILE`]² texels per face side (`resolution / TILE`,
    /// rounded up).
    pub tiles_per_row: u32,
    /// Light texels of all faces in tile-major order (`texel_index` in
    /// `shadow_common.glsl`): every tile has 64, partial edge tiles too.
    pub texels: u64,
    /// Tiles of all faces (`faces · tiles_per_row²`).
    pub tiles: u32,
    /// (triangle, face) pairs caster setup may write.
    pub pair_capacity: u32,
    /// View samples of the run ([`LightInputs::n`]).
    pub n: u32,
    /// Triangles of the run ([`LightInputs::nt`]).
    pub nt: u32,
    /// Mask words per view sample (4 per 128-sample block; 0: hard shadows).
    pub mask_words: u64,
    /// Push constants of every pass (`LightPush`); `more.w`, the occlusion
    /// work units (read by the occlusion passes only), is set once the tiles
    /// are counted.
    pub push: LightPush,
}

impl LightFrame {
    /// Words of the per-tile longest list lengths and, after them, the
    /// tiles' occupancy bits (`occupancy_word` in `shadow_common.glsl`: per
    /// face and row of tiles, `tiles_per_row / 32` words, rounded up).
    pub fn tile_words(&self) -> u64 {
        self.tiles as u64
            + (self.faces * self.tiles_per_row * self.tiles_per_row.div_ceil(32)) as u64
    }

    /// The frame of `inputs` lit by `light` over `resolution`² texels per
    /// face, with `soft`'s samples for a light with extent.
    pub fn new(
        inputs: &LightInputs,
        light: &LightView,
        resolution: u32,
        soft: Option<&SoftLight>,
    ) -> Self {
        let faces = light.face_count() as u32;
        let tiles_per_row = resolution.div_ceil(TILE);
        let tiles_per_face = tiles_per_row * tiles_per_row;
        let (origin, kind, direction, (r, u)) = match light {
            LightView::Point { position } => (
                *position,
                LIGHT_KIND_POINT,
                glam::Vec3::ZERO,
                (glam::Vec3::ZERO, glam::Vec3::ZERO),
            ),
            LightView::Directional { direction } => {
                let (r, u, _) = light.basis(0);
                (glam::Vec3::ZERO, LIGHT_KIND_DIRECTIONAL, *direction, (r, u))
            }
        };
        let pair_capacity = inputs.nt.saturating_mul(faces);
        let base = f32::from_bits(inputs.triangle_base);
        let push = LightPush {
            origin: [origin.x, origin.y, origin.z, f32::from_bits(kind)],
            direction: [direction.x, direction.y, direction.z, 0.0],
            sizes: [inputs.n, inputs.nt, resolution, faces],
            more: [pair_capacity, tiles_per_row, tiles_per_face, 0],
            dir_right: [r.x, r.y, r.z, 0.0],
            dir_up: [u.x, u.y, u.z, 0.0],
            soft: match soft {
                Some(sl) => [0, sl.samples.len() as u32, sl.lut_resolution, 0],
                None => [0; 4],
            },
            soft_light: match soft {
                Some(sl) => [
                    sl.bounds().1,
                    sl.polygon_degree as f32,
                    base,
                    match sl.mode {
                        SoftMode::Lut => LUT_ALLOWANCE_CAP,
                        _ => 0.0,
                    },
                ],
                None => [0.0, 0.0, base, 0.0],
            },
        };
        LightFrame {
            faces,
            resolution,
            tiles_per_row,
            texels: faces as u64 * (tiles_per_row as u64 * TILE as u64).pow(2),
            tiles: faces * tiles_per_face,
            pair_capacity,
            n: inputs.n,
            nt: inputs.nt,
            mask_words: soft.map_or(0, |sl| sl.mask_words() as u64),
            push,
        }
    }

    /// Whether the light has extent (`is_soft` in `shadow_common.glsl`):
    /// the passes whose soft and hard code are separate pipelines pick by it.
    pub fn is_soft(&self) -> bool {
        self.push.soft[1] != 0
    }

    /// The occlusion work units (0 before the tiles are counted).
    pub fn units(&self) -> u32 {
        self.push.more[3]
    }

    /// Sets the occlusion work units.
    pub fn set_units(&mut self, units: u32) {
        self.push.more[3] = units;
    }

    /// Sets which casters the passes take (`caster_in_class` in
    /// `shadow_common.glsl`, a float: an integer's bits would be a denormal
    /// that a driver may flush).
    pub fn set_round(&mut self, round: CasterRound) {
        self.push.dir_up[3] = match round {
            CasterRound::All => 0.0,
            CasterRound::Opaque => 1.0,
            CasterRound::Alpha => 2.0,
        };
    }
}

/// Which casters a round of a light's passes takes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CasterRound {
    /// Every triangle (no triangle is alpha-tested).
    All,
    /// The opaque triangles (the first round when some are alpha-tested).
    Opaque,
    /// The alpha-tested triangles, with their alpha tests (the second round).
    Alpha,
}

impl CasterRound {
    /// The rounds of a run over `inputs`.
    pub fn of(inputs: &LightInputs) -> &'static [CasterRound] {
        if inputs.alpha_casters {
            &[CasterRound::Opaque, CasterRound::Alpha]
        } else {
            &[CasterRound::All]
        }
    }

    /// The prefix of the round's pass names in the timings.
    pub fn prefix(self) -> &'static str {
        match self {
            CasterRound::Alpha => "alpha_",
            _ => "",
        }
    }
}

/// One run being recorded: what every pass's `record` takes. Passes record
/// into `cmd`, each timed by the clock as a named pass
/// ([`Recording::pass`]); [`Recording::submit`] runs what is recorded and
/// starts a new command buffer.
pub struct Recording<'a> {
    /// The device the run records for and submits to.
    pub ctx: &'a GpuContext,
    /// Times each [`Recording::pass`].
    pub clock: &'a mut PassClock,
    /// The command buffer being recorded (replaced by each
    /// [`Recording::submit`]).
    pub cmd: CommandRecorder,
    /// The run's view samples and triangles.
    pub inputs: LightInputs<'a>,
    /// The run's sizes and push constants.
    pub frame: LightFrame,
    /// The casters the passes now take (also their timings' prefix).
    pub round: CasterRound,
    /// A recording into a caller's command buffer
    /// ([`crate::render::Engine::record_frame`]): nothing is submitted or read back,
    /// the occlusion passes run as many units as the GPU counted (indirect
    /// dispatches), and the light's status words go here.
    pub for_caller: Option<BufferSlice<'a>>,
}

impl<'a> Recording<'a> {
    /// Starts round `round`: the casters the next passes take.
    pub fn set_round(&mut self, round: CasterRound) {
        self.round = round;
        self.frame.set_round(round);
    }

    /// Starts recording the run of `frame` over `inputs`.
    pub fn new(
        ctx: &'a GpuContext,
        clock: &'a mut PassClock,
        inputs: LightInputs<'a>,
        frame: LightFrame,
    ) -> Result<Self> {
        Ok(Recording {
            ctx,
            clock,
            cmd: ctx.begin()?,
            inputs,
            frame,
            round: CasterRound::All,
            for_caller: None,
        })
    }

    /// Starts recording the run of `frame` over `inputs` into a caller's
    /// command buffer (`cmd`, [`CommandRecorder::for_caller`]); the light's
    /// status words go to `status`. Passes are not timed.
    pub fn for_caller(
        ctx: &'a GpuContext,
        clock: &'a mut PassClock,
        inputs: LightInputs<'a>,
        frame: LightFrame,
        (cmd, status): (CommandRecorder, BufferSlice<'a>),
    ) -> Self {
        Recording {
            ctx,
            clock,
            cmd,
            inputs,
            frame,
            round: CasterRound::All,
            for_caller: Some(status),
        }
    }

    /// Whether the occlusion passes dispatch the units the GPU counted
    /// (a caller's recording) rather than the host's count.
    pub fn units_indirect(&self) -> bool {
        self.frame.units() == UNITS_INDIRECT
    }

    /// Records `f` as the pass `name` (with the frame's push constants).
    pub fn pass(
        &mut self,
        name: &str,
        f: impl FnOnce(&mut CommandRecorder, &[u8]) -> Result<()>,
    ) -> Result<()> {
        let push = self.frame.push;
        if self.for_caller.is_some() {
            return f(&mut self.cmd, bytemuck::bytes_of(&push));
        }
        let name = format!("{}{name}", self.round.prefix());
        self.clock.time(self.ctx, &mut self.cmd, &name, |rec| {
            f(rec, bytemuck::bytes_of(&push))
        })
    }

    /// Submits what is recorded, waits for it, and starts a new command buffer.
    pub fn submit(&mut self) -> Result<()> {
        if self.for_caller.is_some() {
            return Err(crate::Error::Vulkan(
                "internal: a pass tried to submit a caller's recording".into(),
            ));
        }
        let done = std::mem::replace(&mut self.cmd, self.ctx.begin()?);
        self.ctx.submit_and_wait(done)
    }
}

#[cfg(test)]
mod tests {
    use super::TILE;

    /// The shaders' tile side is this one, and eight: a texel's place in
    /// its tile's lists interleaves three bits of x and y (`in_tile_index`).
    #[test]
    fn tile_side_matches_the_shaders() {
        let shadow_common = include_str!("../../shaders/shadow_common.glsl");
        assert_eq!(
            crate::gpu::shared::tests::glsl_define(shadow_common, "TILE"),
            Some(TILE as u64)
        );
        assert_eq!(TILE, 8);
    }
}
