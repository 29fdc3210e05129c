//! Export for engines: the element mesh as glTF with each light source's radiosity at the
//! vertices, so an engine can relight with its own shader (eq. 1 per vertex).
//!
//! The file holds one mesh (element `j` is triangle `j`, three vertices of its own, the
//! scene's materials, textures, cameras and lights) with, per vertex:
//! - `_RADIOSITY_<SOURCE>` (float VEC3, one per source, e.g. `_RADIOSITY_POINT_0`,
//!   `_RADIOSITY_DIRECTIONAL_1`, `_RADIOSITY_EMISSIVE_3`; a bank is named after its first
//!   light with `BANK_` in front): the radiosity `rho E` (W/m^2 in the scene's units) that
//!   source gives at the vertex with its emission as the scene has it, direct and indirect
//!   (with the ambient term) together, welded vertices taking the area-weighted mean of their elements. An
//!   engine's radiance is `sum_m c_m _RADIOSITY_m / pi` (plus emission) for colours `c_m`;
//! - `COLOR_0`: the radiance under the light state given, times `2^exposure`, clamped to
//!   [0, 1] as glTF requires of colours: a preview, not data (the HDR values are in the
//!   attributes above);
//! - `_SOURCE_COLOR_0` (float VEC3), when the scene has vertex colours (glTF's `COLOR_0`):
//!   the scene's own colours at the vertices, which multiply the albedo (they are already
//!   in the radiosities above).

use std::path::Path;

use glam::Vec3;
use scene_core::gltf_io::{VertexAttribute, export_with};
use scene_core::lights::{LightId, LightState};
use scene_core::{GltfError, Scene};

use crate::display::Welding;
use crate::mesh::Meshing;
use crate::relight;
use crate::solver::{Solution, Source};

/// The attribute name of a source: `_RADIOSITY_POINT_0`, `_RADIOSITY_BANK_EMISSIVE_2`...
pub fn attribute_name(source: &Source) -> String {
    let id = |id: &LightId| match id {
        LightId::Point(i) => format!("POINT_{i}"),
        LightId::Directional(i) => format!("DIRECTIONAL_{i}"),
        LightId::Emissive(i) => format!("EMISSIVE_{i}"),
        LightId::Sky => "SKY".to_string(),
    };
    let first = source.lights.first().map_or_else(|| "NONE".into(), id);
    if source.lights.len() > 1 {
        format!("_RADIOSITY_BANK_{first}")
    } else {
        format!("_RADIOSITY_{first}")
    }
}

/// Writes `path` (`.gltf` or `.glb`): see the module documentation. Nothing is written on
/// an error.
#[allow(clippy::too_many_arguments)]
pub fn gltf(
    scene: &Scene,
    meshing: &Meshing,
    welding: &Welding,
    solution: &Solution,
    state: &LightState,
    exposure: f32,
    path: &Path,
) -> Result<(), GltfError> {
    let k = solution.k();
    let n = meshing.elements.len();
    let per_corner = |vertex: &[Vec3]| -> Vec<Vec3> {
        welding
            .corner_vertex
            .iter()
            .map(|&v| vertex[v as usize])
            .collect()
    };
    let mut attributes = Vec::with_capacity(k + 1);
    for (m, source) in solution.sources.iter().enumerate() {
        let radiosity: Vec<Vec3> = (0..n)
            .map(|j| {
                let s = solution.slot(meshing, j);
                let e = solution.direct[s * k + m] + solution.indirect[s * k + m];
                meshing.elements[j].albedo * e
            })
            .collect();
        attributes.push(VertexAttribute {
            name: attribute_name(source),
            mesh: 0,
            values: per_corner(&welding.vertex_values(meshing, &radiosity)),
        });
    }
    let scale = 2f32.powf(exposure);
    let radiance = relight::radiance(meshing, solution, state);
    let preview: Vec<Vec3> = per_corner(&welding.vertex_values(meshing, &radiance))
        .into_iter()
        .map(|c| {
            let c = c * scale;
            if c.is_finite() {
                c.clamp(Vec3::ZERO, Vec3::ONE)
            } else {
                Vec3::ZERO
            }
        })
        .collect();
    attributes.push(VertexAttribute {
        name: "COLOR_0".into(),
        mesh: 0,
        values: preview,
    });
    let mut elements = meshing.element_scene(scene);
    // The file's own vertex colours (already in each element's albedo, so in the
    // radiosities above) move to `_SOURCE_COLOR_0`: `COLOR_0` holds the preview.
    for (mi, mesh) in elements.meshes.iter_mut().enumerate() {
        if let Some(colors) = mesh.colors.take() {
            attributes.push(VertexAttribute {
                name: "_SOURCE_COLOR_0".into(),
                mesh: mi,
                values: colors,
            });
        }
    }
    elements.name = scene.name.clone();
    elements.point_lights = scene.point_lights.clone();
    elements.directional_lights = scene.directional_lights.clone();
    export_with(&elements, path, &attributes)
}
