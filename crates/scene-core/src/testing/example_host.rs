//! The host side every engine example shares ([`ExampleHost`]): an engine's own device, its
//! camera as reverse-Z matrices with the far plane at infinity (as Bevy builds them), its
//! G-buffer in its own compact formats converted each frame by
//! [`HostGBufferPass`](crate::gpu::HostGBufferPass), an HDR target, and the frame loop that
//! recolours one light over four frames, records the method's
//! [`GpuFrame`](crate::gpu::GpuFrame) into the engine's encoder and counts the GPU objects a
//! steady-state frame creates. An example keeps only what is particular to its method: how
//! the method is prepared.

use glam::{Mat4, Vec3};

use crate::gpu::{FrameInputs, GpuContext, GpuFrame, GpuGBuffer, HostGBufferPass, ObjectCounts};
use crate::lights::{LightId, LightState};
use crate::{DepthConvention, View};

use super::EngineGBuffer;

/// An error of an example run: a GPU fault, a method's, or a check that failed.
pub type ExampleError = Box<dyn std::error::Error>;

/// The light colours of [`ExampleHost::run_light_cycle`], one per frame: white, amber, blue,
/// amber again (the last two frames are the steady state).
pub const LIGHT_CYCLE: [(&str, Vec3); 4] = [
    ("white", Vec3::ONE),
    ("amber", Vec3::new(1.0, 0.6, 0.2)),
    ("blue", Vec3::new(0.3, 0.5, 1.0)),
    ("amber", Vec3::new(1.0, 0.6, 0.2)),
];

/// An engine as the examples stand one in (module docs): its device, camera and G-buffer,
/// set up once, and the frame loop.
#[derive(Debug)]
pub struct ExampleHost {
    /// The engine's device, as the methods take it.
    pub ctx: GpuContext,
    /// The toolkit's view of the engine's camera.
    pub view: View,
    /// The depth convention of the engine's projection.
    pub depth: DepthConvention,
    engine: EngineGBuffer,
    convert: HostGBufferPass,
    gbuffer: GpuGBuffer,
    target: wgpu::Texture,
}

impl ExampleHost {
    /// The engine's own device and queue (any wgpu device will do: the methods run on it
    /// through [`GpuContext::from_device`]); prints the adapter.
    pub fn engine_context() -> Result<GpuContext, ExampleError> {
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let adapter = pollster::block_on(instance.request_adapter(&Default::default()))?;
        let (device, queue) =
            pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
                label: Some("engine"),
                required_limits: adapter.limits(),
                ..Default::default()
            }))?;
        let ctx = GpuContext::from_device(device, queue);
        println!("adapter: {}", ctx.adapter_summary());
        Ok(ctx)
    }

    /// The engine's camera matrices (right-handed, depth in [0, 1], reversed with the far
    /// plane at infinity) for an eye looking at `target` with a vertical field of view of
    /// `fov_y` radians over a `width x height` image.
    pub fn engine_matrices(
        eye: Vec3,
        target: Vec3,
        fov_y: f32,
        (width, height): (u32, u32),
    ) -> (Mat4, Mat4) {
        let view = glam::camera::rh::view::look_at_mat4(eye, target, Vec3::Y);
        let aspect = width as f32 / height as f32;
        let proj =
            glam::camera::rh::proj::directx::perspective_infinite_reverse(fov_y, aspect, 0.05);
        (view, proj)
    }

    /// The host for the engine's camera `matrices` and a `width x height` G-buffer that
    /// `draw` makes in the engine's formats for the view and depth convention the matrices
    /// give ([`EngineGBuffer::compact`] or [`EngineGBuffer::from_texels`]). Makes the
    /// converter, the toolkit G-buffer and an `Rgba32Float` target (an engine's
    /// `Rgba16Float` works too; 32-bit floats read back here).
    pub fn new(
        ctx: GpuContext,
        (view_matrix, projection): (Mat4, Mat4),
        (width, height): (u32, u32),
        draw: impl FnOnce(&GpuContext, &View, &DepthConvention) -> Result<EngineGBuffer, ExampleError>,
    ) -> Result<Self, ExampleError> {
        let (view, depth) = View::from_host_matrices(view_matrix, projection)?;
        println!(
            "camera: reverse-Z {}, infinite far {} (the toolkit's far plane {:.0} m)",
            depth.reverse, depth.infinite, view.far
        );
        let engine = draw(&ctx, &view, &depth)?;
        let target = ctx.create_texture_2d(
            "engine frame",
            width,
            height,
            wgpu::TextureFormat::Rgba32Float,
            wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::COPY_SRC,
        );
        Ok(Self {
            convert: HostGBufferPass::new(&ctx)?,
            gbuffer: GpuGBuffer::new(&ctx, width, height)?,
            ctx,
            view,
            depth,
            engine,
            target,
        })
    }

    /// `scene` drawn for the view by scene-core's ray caster (standing in for an engine's
    /// raster pass) and kept in the engine's compact formats, without ids: a `draw` for
    /// [`ExampleHost::new`].
    #[cfg(feature = "rays")]
    pub fn ray_cast(
        scene: &crate::Scene,
        (width, height): (u32, u32),
    ) -> impl FnOnce(&GpuContext, &View, &DepthConvention) -> Result<EngineGBuffer, ExampleError> + '_
    {
        move |ctx, view, depth| {
            use crate::GBufferRenderer;
            let own = crate::gbuffer::RayCastRenderer::new().render(scene, view, width, height)?;
            Ok(EngineGBuffer::compact(ctx, &own, view.far, depth)?)
        }
    }

    /// The toolkit G-buffer each frame converts the engine's into.
    pub fn gbuffer(&self) -> &GpuGBuffer {
        &self.gbuffer
    }

    /// The HDR target frames are written into.
    pub fn target(&self) -> &wgpu::Texture {
        &self.target
    }

    /// Runs four frames of `method`, one per colour of [`LIGHT_CYCLE`] given to `light`:
    /// each converts the engine's G-buffer and records the method's frame into one encoder
    /// of the engine, submits it, reads the target back and prints its mean radiance. Then
    /// checks that the amber light dimmed blue (the frame followed the light change) and
    /// prints the GPU objects the steady-state frames created (wgpu's counters; all zero on
    /// the frame contract). Returns the four means.
    pub fn run_light_cycle(
        &mut self,
        method: &mut dyn GpuFrame,
        light: LightId,
    ) -> Result<Vec<Vec3>, ExampleError> {
        let mut steady = ObjectCounts::default();
        let mut means = Vec::new();
        for (frame, (label, colour)) in LIGHT_CYCLE.into_iter().enumerate() {
            let mut state = LightState::new();
            state.set_color(light, colour);
            let mut encoder = self.ctx.device.create_command_encoder(&Default::default());
            let (result, created) = ObjectCounts::during(&self.ctx.device, || {
                let host = self.engine.host();
                self.convert
                    .encode(&mut encoder, &host, &self.depth, &self.gbuffer)?;
                let inputs = FrameInputs {
                    gbuffer: &self.gbuffer,
                    view: &self.view,
                    lights: &state,
                };
                method.encode(&mut encoder, &inputs, &self.target)
            });
            result?;
            if frame > 0 {
                steady = created;
            }
            self.ctx.queue.submit([encoder.finish()]);
            let mean = self.ctx.read_texture_image(&self.target)?.mean();
            println!("{} ({label} light): mean radiance {mean:.4}", method.name());
            means.push(mean);
        }
        if !(means[1].z < 0.3 * means[0].z && means[1].x > 0.9 * means[0].x) {
            return Err(format!(
                "the frame did not follow the light change: white {}, amber {}",
                means[0], means[1]
            )
            .into());
        }
        println!("{}", steady.steady_state_line(&self.ctx.device));
        Ok(means)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_failing_draw_is_the_hosts_error() {
        let Some(ctx) = crate::testing::gpu_test_context() else {
            return;
        };
        let m = ExampleHost::engine_matrices(Vec3::new(0.0, 1.0, 3.0), Vec3::ZERO, 1.0, (8, 6));
        let e = ExampleHost::new(ctx, m, (8, 6), |_, _, _| Err("no engine".into())).unwrap_err();
        assert_eq!(e.to_string(), "no engine");
    }

    #[test]
    fn the_matrices_are_reverse_z_with_an_infinite_far_plane() {
        let m = ExampleHost::engine_matrices(Vec3::new(0.0, 1.0, 3.0), Vec3::ZERO, 1.0, (8, 6));
        let (_, depth) = View::from_host_matrices(m.0, m.1).unwrap();
        assert!(depth.reverse && depth.infinite);
    }
}
