//! A stable hash for cache keys, state fingerprints and file names: the same value on every
//! platform, Rust version and run (unlike `std`'s `DefaultHasher`).

/// 64-bit FNV-1a: stable across platforms, Rust versions and runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Fnv(u64);

impl Default for Fnv {
    fn default() -> Self {
        Self(0xcbf2_9ce4_8422_2325)
    }
}

impl Fnv {
    /// Feeds bytes.
    pub fn bytes(&mut self, b: &[u8]) -> &mut Self {
        for &x in b {
            self.0 ^= x as u64;
            self.0 = self.0.wrapping_mul(0x0100_0000_01b3);
        }
        self
    }

    /// Feeds a string (length-prefixed).
    pub fn str(&mut self, s: &str) -> &mut Self {
        self.u64(s.len() as u64).bytes(s.as_bytes())
    }

    /// Feeds an integer.
    pub fn u64(&mut self, v: u64) -> &mut Self {
        self.bytes(&v.to_le_bytes())
    }

    /// Feeds floats by their bits.
    pub fn f32s(&mut self, v: impl IntoIterator<Item = f32>) -> &mut Self {
        for x in v {
            self.bytes(&x.to_bits().to_le_bytes());
        }
        self
    }

    /// The hash.
    pub fn finish(&self) -> u64 {
        self.0
    }
}

/// The identity of a scene's content: a 64-bit hash of everything light transport sees
/// (mesh positions, normals, UVs, indices and material ids; materials; textures; point and
/// directional lights), not its name or cameras. The one scene identity of the toolkit:
/// cache keys of reference images use it, and it tells whether two scenes are the same.
///
/// Large arrays are hashed in fixed 256 KiB chunks on the rayon pool with a word-at-a-time
/// multiply-rotate mix, the chunks combined in order, so the value does not depend on the
/// thread count (about 10 ms for 10^6 triangles on 2 cores). It is not cryptographic: do not
/// key anything on it that an adversary controls.
pub fn scene_content_hash(scene: &crate::Scene) -> u64 {
    use rayon::prelude::*;
    fn mix(h: u64, w: u64) -> u64 {
        (h.rotate_left(5) ^ w).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95)
    }
    fn words(h: u64, bytes: &[u8]) -> u64 {
        const CHUNK: usize = 1 << 18;
        let parts: Vec<u64> = bytes
            .par_chunks(CHUNK)
            .map(|c| {
                let mut h = 0x243f_6a88_85a3_08d3u64;
                let mut it = c.chunks_exact(8);
                for w in &mut it {
                    h = mix(h, u64::from_le_bytes(w.try_into().unwrap_or([0; 8])));
                }
                for &b in it.remainder() {
                    h = mix(h, b as u64);
                }
                h
            })
            .collect();
        let mut h = mix(h, bytes.len() as u64);
        for p in parts {
            h = mix(h, p);
        }
        h
    }
    let mut h = mix(0, scene.meshes.len() as u64);
    for m in &scene.meshes {
        h = words(h, bytemuck::cast_slice(&m.positions));
        h = words(h, bytemuck::cast_slice(&m.normals));
        h = match &m.uvs {
            Some(uvs) => words(mix(h, 1), bytemuck::cast_slice(uvs)),
            None => mix(h, 0),
        };
        h = match &m.colors {
            Some(c) => words(mix(h, 1), bytemuck::cast_slice(c)),
            None => mix(h, 0),
        };
        h = words(h, bytemuck::cast_slice(&m.indices));
        h = words(h, bytemuck::cast_slice(&m.material_ids));
    }
    h = mix(h, scene.materials.len() as u64);
    for m in &scene.materials {
        h = words(h, bytemuck::cast_slice(&[m.albedo, m.emission]));
        h = mix(h, m.albedo_texture.map_or(u64::MAX, u64::from));
        h = mix(
            h,
            m.alpha_cutoff.map_or(u64::MAX, |c| u64::from(c.to_bits())),
        );
    }
    h = mix(h, scene.textures.len() as u64);
    for t in &scene.textures {
        h = mix(mix(h, t.width as u64), t.height as u64);
        h = words(h, bytemuck::cast_slice(&t.texels));
        h = mix(h, u64::from(t.sampler.bits()));
        h = match &t.alpha {
            Some(a) => words(mix(h, 1), bytemuck::cast_slice(a)),
            None => mix(h, 0),
        };
    }
    h = mix(h, scene.point_lights.len() as u64);
    for l in &scene.point_lights {
        let r = l.radius.map_or(-1.0, |r| r);
        h = words(h, bytemuck::cast_slice(&[l.position, l.intensity]));
        h = mix(h, r.to_bits() as u64);
        if let Some(c) = &l.cone {
            h = words(h, bytemuck::cast_slice(&[c.direction]));
            h = mix(mix(h, c.inner.to_bits() as u64), c.outer.to_bits() as u64);
        } else {
            h = mix(h, u64::MAX);
        }
    }
    h = mix(h, scene.directional_lights.len() as u64);
    for l in &scene.directional_lights {
        h = words(h, bytemuck::cast_slice(&[l.direction, l.irradiance]));
    }
    h = match &scene.sky {
        Some(sky) => {
            let (w, hh) = sky.size();
            let h = mix(mix(mix(h, 1), u64::from(w)), u64::from(hh));
            mix(
                words(h, bytemuck::cast_slice(sky.map())),
                u64::from(sky.directions()),
            )
        }
        None => mix(h, 0),
    };
    h
}

#[cfg(test)]
mod tests {
    use super::Fnv;

    #[test]
    fn content_hash_sees_geometry_materials_and_lights_but_not_names() {
        use super::scene_content_hash as hash;
        let base = crate::builtin::scene("cornell-point").unwrap();
        let h0 = hash(&base);
        let mut s = base.clone();
        s.name = "renamed".into();
        s.cameras.clear();
        assert_eq!(hash(&s), h0, "name and cameras are not content");
        type Edit = (&'static str, fn(&mut crate::Scene));
        let edits: [Edit; 7] = [
            ("a vertex", |s| s.meshes[0].positions[0].x += 1e-3),
            ("an albedo", |s| s.materials[0].albedo.y *= 0.5),
            ("a light position", |s| s.point_lights[0].position.y -= 0.01),
            ("a light intensity", |s| s.point_lights[0].intensity *= 2.0),
            ("a light radius", |s| s.point_lights[0].radius = Some(3.0)),
            ("a sky", |s| {
                s.sky = Some(crate::sky::Sky::uniform(glam::Vec3::ONE).unwrap())
            }),
            ("a spot cone", |s| {
                s.point_lights[0].cone = Some(crate::lights::SpotCone {
                    direction: glam::Vec3::NEG_Y,
                    inner: 0.2,
                    outer: 0.5,
                })
            }),
        ];
        for (what, edit) in edits {
            let mut s = base.clone();
            edit(&mut s);
            assert_ne!(hash(&s), h0, "editing {what} must change the hash");
        }
        // The same on any thread count.
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        assert_eq!(one.install(|| hash(&base)), h0);
    }

    #[test]
    fn fnv1a_reference_values() {
        // Published FNV-1a 64 test vectors.
        assert_eq!(Fnv::default().finish(), 0xcbf2_9ce4_8422_2325);
        assert_eq!(Fnv::default().bytes(b"a").finish(), 0xaf63_dc4c_8601_ec8c);
        assert_eq!(
            Fnv::default().bytes(b"foobar").finish(),
            0x8594_4171_f739_67e8
        );
    }
}
