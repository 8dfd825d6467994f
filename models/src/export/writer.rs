//! The one glTF writer of the exports: a typed document ([`gltf_json::Root`]) grown object by object
//! beside its binary buffer, and the GLB container around both. The URDF character export
//! ([`super::gltf`]) builds its document from nothing; the rig clip export ([`super::rig`]) starts from
//! the creature's own file.

use gltf_json as json;
use nalgebra::{UnitQuaternion, Vector3};
use json::accessor::{ComponentType, GenericComponentType, Type};
use json::animation::{Channel, Interpolation, Property, Sampler, Target};
use json::validation::{Checked, USize64};
use json::{Index, Root};

use super::ExportProblem;

/// A glTF document under construction with its binary buffer (buffer 0, the GLB's binary chunk) and
/// the animation being written.
pub struct Builder {
    pub root: Root,
    pub bin: Vec<u8>,
    /// Samplers and channels of the animation [`Builder::finish`] adds (when it has channels).
    samplers: Vec<Sampler>,
    channels: Vec<Channel>,
}

impl Builder {
    /// A builder over `root`, whose buffer 0 (if any) is `bin`.
    pub fn new(root: Root, bin: Vec<u8>) -> Self {
        Builder {
            root,
            bin,
            samplers: Vec::new(),
            channels: Vec::new(),
        }
    }

    /// Appends `bytes` as a buffer view starting on a 4-byte boundary (what every accessor's component
    /// type needs).
    pub fn view(&mut self, bytes: &[u8], target: Option<json::buffer::Target>) -> Index<json::buffer::View> {
        self.bin.resize(self.bin.len().next_multiple_of(4), 0);
        let view = json::buffer::View {
            buffer: Index::new(0),
            byte_length: USize64::from(bytes.len()),
            byte_offset: Some(USize64::from(self.bin.len())),
            byte_stride: None,
            name: None,
            target: target.map(Checked::Valid),
            extensions: None,
            extras: Default::default(),
        };
        self.bin.extend_from_slice(bytes);
        self.root.push(view)
    }

    /// A float accessor of `width` components per element (1, 3, 4 or 16 for 4×4 matrices), with min/max
    /// when `bounds`.
    pub fn floats(
        &mut self,
        data: &[f32],
        width: usize,
        target: Option<json::buffer::Target>,
        bounds: bool,
    ) -> Index<json::Accessor> {
        let bytes: Vec<u8> = data.iter().flat_map(|v| v.to_le_bytes()).collect();
        let view = self.view(&bytes, target);
        let kind = match width {
            1 => Type::Scalar,
            3 => Type::Vec3,
            4 => Type::Vec4,
            16 => Type::Mat4,
            _ => unreachable!("accessor width {width}"),
        };
        let (mut min, mut max) = (None, None);
        if bounds {
            // Exactly the stored f32 values: serde_json keeps f32 → f64 exact, validators compare exactly.
            let mut lo = vec![f32::INFINITY; width];
            let mut hi = vec![f32::NEG_INFINITY; width];
            for e in data.chunks_exact(width) {
                for c in 0..width {
                    lo[c] = lo[c].min(e[c]);
                    hi[c] = hi[c].max(e[c]);
                }
            }
            min = Some(json::Value::from(lo));
            max = Some(json::Value::from(hi));
        }
        self.accessor(view, ComponentType::F32, data.len() / width, kind, min, max)
    }

    /// A triangle index accessor, 16-bit when the vertices allow it.
    pub fn indices(&mut self, indices: &[u32], vertex_count: usize) -> Index<json::Accessor> {
        // 65535 is the primitive-restart value of 16-bit indices and may not be used.
        let (bytes, component): (Vec<u8>, ComponentType) = if vertex_count <= 65535 {
            (
                indices.iter().flat_map(|&i| (i as u16).to_le_bytes()).collect(),
                ComponentType::U16,
            )
        } else {
            (
                indices.iter().flat_map(|i| i.to_le_bytes()).collect(),
                ComponentType::U32,
            )
        };
        let view = self.view(&bytes, Some(json::buffer::Target::ElementArrayBuffer));
        self.accessor(view, component, indices.len(), Type::Scalar, None, None)
    }

    fn accessor(
        &mut self,
        view: Index<json::buffer::View>,
        component: ComponentType,
        count: usize,
        kind: Type,
        min: Option<json::Value>,
        max: Option<json::Value>,
    ) -> Index<json::Accessor> {
        self.root.push(json::Accessor {
            buffer_view: Some(view),
            byte_offset: None,
            count: USize64::from(count),
            component_type: Checked::Valid(GenericComponentType(component)),
            extensions: None,
            extras: Default::default(),
            type_: Checked::Valid(kind),
            min,
            max,
            name: None,
            normalized: false,
            sparse: None,
        })
    }

    /// A LINEAR sampler over the time accessor `input` and a channel driving `path` of `node` with
    /// `values` (3 floats per key for translations and scales, 4 for rotations).
    pub fn channel(&mut self, node: usize, path: Property, input: Index<json::Accessor>, values: &[f32]) {
        let width = if path == Property::Rotation { 4 } else { 3 };
        let output = self.floats(values, width, None, false);
        let sampler = Index::push(
            &mut self.samplers,
            Sampler {
                extensions: None,
                extras: Default::default(),
                input,
                interpolation: Checked::Valid(Interpolation::Linear),
                output,
            },
        );
        self.channels.push(Channel {
            sampler,
            target: Target {
                extensions: None,
                extras: Default::default(),
                node: Index::new(node as u32),
                path: Checked::Valid(path),
            },
            extensions: None,
            extras: Default::default(),
        });
    }

    /// Adds the animation of the channels written so far, named `name`, and sets buffer 0 to the
    /// binary data (no URI: the GLB's binary chunk). Returns the document and the binary data.
    pub fn finish(mut self, name: &str) -> (Root, Vec<u8>) {
        if !self.channels.is_empty() {
            self.root.push(json::Animation {
                extensions: None,
                extras: Default::default(),
                channels: std::mem::take(&mut self.channels),
                name: Some(name.to_owned()),
                samplers: std::mem::take(&mut self.samplers),
            });
        }
        self.bin.resize(self.bin.len().next_multiple_of(4), 0);
        let buffer = json::Buffer {
            byte_length: USize64::from(self.bin.len()),
            name: None,
            uri: None,
            extensions: None,
            extras: Default::default(),
        };
        if self.root.buffers.is_empty() {
            self.root.push(buffer);
        } else {
            self.root.buffers[0] = buffer;
        }
        (self.root, self.bin)
    }
}

/// Translations (or scales) as accessor values.
pub fn vec3_values(v: &[Vector3<f32>]) -> Vec<f32> {
    v.iter().flat_map(|t| [t.x, t.y, t.z]).collect()
}

/// Rotations as accessor values `x y z w`, each flipped when needed to stay in the hemisphere of the
/// previous one (q and −q are the same rotation, but LINEAR interpolation between keys of opposite
/// sign would turn the long way round).
pub fn quat_values(rotations: &[UnitQuaternion<f32>]) -> Vec<f32> {
    let mut out = Vec::with_capacity(4 * rotations.len());
    let mut prev: Option<nalgebra::Quaternion<f32>> = None;
    for r in rotations {
        let mut q = r.normalize();
        if prev.is_some_and(|p| p.dot(&q) < 0.0) {
            q = -q;
        }
        out.extend_from_slice(&[q.i, q.j, q.k, q.w]);
        prev = Some(q);
    }
    out
}

/// The GLB container of `root` and its binary chunk `bin` (buffer 0): 12-byte header, the JSON chunk
/// padded with spaces and the binary chunk padded with zeros, each to a multiple of 4 bytes.
pub fn glb(root: &Root, bin: &[u8]) -> Result<Vec<u8>, ExportProblem> {
    let json = root.to_vec().expect("a glTF document serialises");
    let total = 12 + 8 + json.len().next_multiple_of(4) + 8 + bin.len().next_multiple_of(4);
    if u32::try_from(total).is_err() {
        return Err(ExportProblem::TooLarge(total));
    }
    let header = ::gltf::binary::Header {
        magic: *b"glTF",
        version: 2,
        length: total as u32,
    };
    let out = ::gltf::Glb {
        header,
        json: json.into(),
        bin: Some(bin.into()),
    }
    .to_vec()
    .map_err(|e| ExportProblem::Io(std::io::Error::other(e.to_string())))?;
    debug_assert_eq!(out.len(), total);
    Ok(out)
}

/// The glTF JSON form of a GLB that [`glb`] wrote: its document with buffer 0 holding the binary
/// chunk as a base64 data URI (for an output named `.gltf`: one self-contained file).
pub fn gltf_text(glb_bytes: &[u8]) -> Result<Vec<u8>, ExportProblem> {
    let bad = |e: &dyn std::fmt::Display| ExportProblem::Io(std::io::Error::other(format!("the model just built does not read back: {e}")));
    let g = ::gltf::Glb::from_slice(glb_bytes).map_err(|e| bad(&e))?;
    let mut root = Root::from_slice(&g.json).map_err(|e| bad(&e))?;
    if let (Some(bin), Some(buffer)) = (g.bin, root.buffers.first_mut()) {
        let data = bin.get(..buffer.byte_length.0 as usize).unwrap_or(&bin);
        buffer.uri = Some(format!("data:application/octet-stream;base64,{}", base64::Engine::encode(&base64::engine::general_purpose::STANDARD, data)));
    }
    root.to_vec_pretty().map_err(|e| bad(&e))
}

impl Default for Builder {
    /// An empty document (glTF 2.0) and no binary data.
    fn default() -> Self {
        Builder::new(Root::default(), Vec::new())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn component(b: &Builder, a: Index<json::Accessor>) -> ComponentType {
        match b.root.get(a).unwrap().component_type {
            Checked::Valid(GenericComponentType(c)) => c,
            Checked::Invalid => panic!("invalid component type"),
        }
    }

    #[test]
    fn views_start_on_four_byte_boundaries_in_the_one_buffer() {
        let mut b = Builder::default();
        let first = b.view(&[1, 2, 3], None);
        let second = b.view(&[4, 5], Some(json::buffer::Target::ArrayBuffer));
        assert_eq!(b.bin, [1, 2, 3, 0, 4, 5]);
        let (v1, v2) = (b.root.get(first).unwrap(), b.root.get(second).unwrap());
        assert_eq!((v1.byte_offset, v1.byte_length), (Some(USize64(0)), USize64(3)));
        assert_eq!((v2.byte_offset, v2.byte_length), (Some(USize64(4)), USize64(2)));
        assert_eq!(v2.target, Some(Checked::Valid(json::buffer::Target::ArrayBuffer)));
        assert_eq!(v1.buffer.value(), 0);
    }

    #[test]
    fn float_accessors_count_elements_and_bound_each_component_exactly() {
        let mut b = Builder::default();
        let data = [1.0, -2.0, 0.1, -3.5, 4.0, 0.2];
        let a = b.floats(&data, 3, None, true);
        let acc = b.root.get(a).unwrap();
        assert_eq!((acc.count, acc.type_), (USize64(2), Checked::Valid(Type::Vec3)));
        assert_eq!(component(&b, a), ComponentType::F32);
        assert_eq!(acc.min, Some(json::Value::from(vec![-3.5f32, -2.0, 0.1])));
        assert_eq!(acc.max, Some(json::Value::from(vec![1.0f32, 4.0, 0.2])));
        assert_eq!(b.bin, data.iter().flat_map(|v| v.to_le_bytes()).collect::<Vec<u8>>());
        for (width, kind) in [(1, Type::Scalar), (4, Type::Vec4), (16, Type::Mat4)] {
            let a = b.floats(&[0.0; 16], width, None, false);
            let acc = b.root.get(a).unwrap();
            assert_eq!((acc.count, acc.type_, acc.min.clone()), (USize64((16 / width) as u64), Checked::Valid(kind), None));
        }
    }

    #[test]
    fn indices_are_sixteen_bit_up_to_65535_vertices() {
        let mut b = Builder::default();
        let small = b.indices(&[0, 1, 65534], 65535);
        assert_eq!(component(&b, small), ComponentType::U16);
        assert_eq!(b.bin, [0, 0, 1, 0, 0xFE, 0xFF]);
        let large = b.indices(&[0, 1, 65535], 65536);
        assert_eq!(component(&b, large), ComponentType::U32);
        assert_eq!(b.bin[8..], [0, 0, 0, 0, 1, 0, 0, 0, 0xFF, 0xFF, 0, 0]);
        assert_eq!(b.root.get(large).unwrap().count, USize64(3));
    }

    #[test]
    fn rotations_stay_in_one_hemisphere_from_key_to_key() {
        let r = |angle: f32| UnitQuaternion::from_axis_angle(&Vector3::z_axis(), angle);
        // 350° is −10°: its quaternion (w = cos 175° < 0) is flipped to follow the first key's.
        let v = quat_values(&[r(0.0), r(350f32.to_radians()), r(340f32.to_radians())]);
        let (s5, c5) = 5f32.to_radians().sin_cos();
        let (s10, c10) = 10f32.to_radians().sin_cos();
        let expect = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, -s5, c5, 0.0, 0.0, -s10, c10];
        assert!(v.iter().zip(expect).all(|(a, b)| (a - b).abs() < 1e-6), "{v:?}");
        assert_eq!(vec3_values(&[Vector3::new(1.0, 2.0, 3.0), Vector3::new(4.0, 5.0, 6.0)]), [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]);
    }

    #[test]
    fn the_animation_and_buffer_are_written_at_the_end() {
        // No channels: no animation; the buffer is the padded binary data.
        let mut b = Builder::default();
        b.view(&[7; 5], None);
        let (root, bin) = b.finish("walk");
        assert!(root.animations.is_empty());
        assert_eq!((bin.len(), root.buffers.len(), root.buffers[0].byte_length), (8, 1, USize64(8)));
        // A file's own buffer 0 is replaced, not added to; the channels make one animation.
        let mut file = Root::default();
        file.push(json::Buffer { byte_length: USize64(99), name: None, uri: Some("old.bin".into()), extensions: None, extras: Default::default() });
        let mut b = Builder::new(file, vec![1, 2, 3, 4]);
        let times = b.floats(&[0.0, 0.5], 1, None, true);
        b.channel(0, Property::Rotation, times, &[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]);
        b.channel(1, Property::Translation, times, &[0.0; 6]);
        let (root, bin) = b.finish("walk");
        assert_eq!((root.buffers.len(), root.buffers[0].byte_length, root.buffers[0].uri.clone()), (1, USize64(bin.len() as u64), None));
        let anim = &root.animations[0];
        assert_eq!((anim.name.as_deref(), anim.channels.len(), anim.samplers.len()), (Some("walk"), 2, 2));
        assert_eq!(anim.channels[1].target.node.value(), 1);
        assert_eq!(anim.channels[1].sampler.value(), 1);
        assert_eq!(anim.channels[0].target.path, Checked::Valid(Property::Rotation));
        let out = |i: usize| root.get(anim.samplers[i].output).unwrap().clone();
        assert_eq!((out(0).type_, out(0).count), (Checked::Valid(Type::Vec4), USize64(2)));
        assert_eq!((out(1).type_, out(1).count), (Checked::Valid(Type::Vec3), USize64(2)));
        assert_eq!(anim.samplers[1].input, times);
        assert_eq!(anim.samplers[0].interpolation, Checked::Valid(Interpolation::Linear));
    }

    #[test]
    fn a_glb_is_its_header_then_the_padded_json_and_binary_chunks() {
        let mut b = Builder::default();
        b.view(&[9; 6], None);
        let (root, bin) = b.finish("clip");
        let out = glb(&root, &bin).unwrap();
        let json = root.to_vec().unwrap();
        let json_len = json.len().next_multiple_of(4);
        assert_eq!(&out[..4], b"glTF");
        assert_eq!(u32::from_le_bytes(out[4..8].try_into().unwrap()), 2);
        assert_eq!(u32::from_le_bytes(out[8..12].try_into().unwrap()) as usize, out.len());
        assert_eq!(out.len(), 12 + 8 + json_len + 8 + 8);
        assert_eq!(&out[20..20 + json.len()], json.as_slice());
        assert!(out[20 + json.len()..20 + json_len].iter().all(|&c| c == b' '));
        assert_eq!(&out[28 + json_len..], [9, 9, 9, 9, 9, 9, 0, 0]);
    }
}
