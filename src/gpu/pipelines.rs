//! The five compute pipelines, built once per renderer. Each pass's WGSL is common.wgsl
//! followed by the pass's own file and, for the gather passes, where they read their
//! looped-over records ([`Tiles`]); compiled into the binary.

use std::num::NonZeroU64;

use super::layout::{CHUNK_BYTES, DispatchParams};

/// shaders/common.wgsl.
pub const COMMON_WGSL: &str = include_str!("../../shaders/common.wgsl");

/// Where the gather passes (forward, backward_normal, backward_texel) read the records they
/// loop over.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Tiles {
    /// A storage buffer, a tile of `WG` records at a time loaded into workgroup memory that
    /// the whole workgroup reads (shaders/tile_workgroup.wgsl): GPUs.
    Workgroup,
    /// One uniform chunk per dispatch (shaders/tile_uniform.wgsl): software adapters such
    /// as lavapipe, which read storage and workgroup memory in loops lane by lane.
    Uniform,
}

/// The passes, each one entry point of the same name in shaders/NAME.wgsl.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Pass {
    /// The image.
    Forward,
    /// dLoss/dn per pixel.
    BackwardNormal,
    /// dLoss/dL and the dctrl shares per texel.
    BackwardTexel,
    /// dLoss/dctrl from the shares.
    ReduceCtrl,
    /// The sum over slices of the other passes' partial sums.
    ReduceSlices,
}

impl Pass {
    /// Every pass.
    pub const ALL: [Pass; 5] = [
        Pass::Forward,
        Pass::BackwardNormal,
        Pass::BackwardTexel,
        Pass::ReduceCtrl,
        Pass::ReduceSlices,
    ];

    /// The entry point (and file stem).
    pub fn name(self) -> &'static str {
        match self {
            Pass::Forward => "forward",
            Pass::BackwardNormal => "backward_normal",
            Pass::BackwardTexel => "backward_texel",
            Pass::ReduceCtrl => "reduce_ctrl",
            Pass::ReduceSlices => "reduce_slices",
        }
    }

    /// Whether the pass loops over records read through [`Tiles`].
    pub fn is_gather(self) -> bool {
        matches!(
            self,
            Pass::Forward | Pass::BackwardNormal | Pass::BackwardTexel
        )
    }

    /// The pass's WGSL module as assembled: common.wgsl, (gather passes) gather.wgsl, the
    /// pass, then (gather passes) the file of `tiles`.
    pub fn source(self, tiles: Tiles) -> String {
        let own = match self {
            Pass::Forward => include_str!("../../shaders/forward.wgsl"),
            Pass::BackwardNormal => include_str!("../../shaders/backward_normal.wgsl"),
            Pass::BackwardTexel => include_str!("../../shaders/backward_texel.wgsl"),
            Pass::ReduceCtrl => include_str!("../../shaders/reduce_ctrl.wgsl"),
            Pass::ReduceSlices => include_str!("../../shaders/reduce_slices.wgsl"),
        };
        let tile = match tiles {
            _ if !self.is_gather() => "",
            Tiles::Workgroup => include_str!("../../shaders/tile_workgroup.wgsl"),
            Tiles::Uniform => include_str!("../../shaders/tile_uniform.wgsl"),
        };
        let gather = if self.is_gather() {
            include_str!("../../shaders/gather.wgsl")
        } else {
            ""
        };
        format!("{COMMON_WGSL}\n{gather}\n{own}\n{tile}")
    }

    /// The storage bindings after `params` and (gather passes) the tiled records at
    /// binding 1: (read-only count, read-write count).
    fn bindings(self) -> (u32, u32) {
        match self {
            Pass::Forward | Pass::BackwardNormal => (1, 1),
            Pass::BackwardTexel => (1, 2),
            Pass::ReduceCtrl | Pass::ReduceSlices => (1, 1),
        }
    }
}

/// A pass's pipeline and bind group layout.
pub struct Pipeline {
    /// The pipeline.
    pub pipeline: wgpu::ComputePipeline,
    /// Its group 0 layout.
    pub layout: wgpu::BindGroupLayout,
}

fn buffer_entry(
    binding: u32,
    ty: wgpu::BufferBindingType,
    dynamic: bool,
    min: u64,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty,
            has_dynamic_offset: dynamic,
            min_binding_size: NonZeroU64::new(min),
        },
        count: None,
    }
}

impl Pipeline {
    /// Compiles `pass` on `device`, its records read through `tiles`, through `cache`
    /// where there is one.
    pub fn new(
        device: &wgpu::Device,
        pass: Pass,
        tiles: Tiles,
        cache: Option<&wgpu::PipelineCache>,
    ) -> Self {
        let (ro, rw) = pass.bindings();
        // the params: an array of scenes (a batch in z) in storage for the gather passes on
        // workgroup tiles and for reduce_ctrl
        let params = if pass == Pass::ReduceCtrl || (pass.is_gather() && tiles == Tiles::Workgroup)
        {
            wgpu::BufferBindingType::Storage { read_only: true }
        } else {
            wgpu::BufferBindingType::Uniform
        };
        let mut entries = vec![buffer_entry(
            0,
            params,
            true,
            size_of::<DispatchParams>() as u64,
        )];
        if pass.is_gather() {
            entries.push(match tiles {
                Tiles::Workgroup => buffer_entry(
                    1,
                    wgpu::BufferBindingType::Storage { read_only: true },
                    false,
                    0,
                ),
                Tiles::Uniform => {
                    buffer_entry(1, wgpu::BufferBindingType::Uniform, false, CHUNK_BYTES)
                }
            });
        }
        for _ in 0..ro {
            let b = entries.len() as u32;
            entries.push(buffer_entry(
                b,
                wgpu::BufferBindingType::Storage { read_only: true },
                false,
                0,
            ));
        }
        for _ in 0..rw {
            let b = entries.len() as u32;
            entries.push(buffer_entry(
                b,
                wgpu::BufferBindingType::Storage { read_only: false },
                false,
                0,
            ));
        }
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some(pass.name()),
            entries: &entries,
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some(pass.name()),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some(pass.name()),
            source: wgpu::ShaderSource::Wgsl(pass.source(tiles).into()),
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(pass.name()),
            layout: Some(&pipeline_layout),
            module: &module,
            entry_point: Some(pass.name()),
            compilation_options: Default::default(),
            cache,
        });
        Pipeline { pipeline, layout }
    }
}
