//! The GLB's binary chunk as it is built: bytes, buffer views and accessors (glTF 2.0 spec
//! 3.6), shared by the mesh and the animation writers.

use serde_json::{json, Map, Value};

/// glTF accessor.componentType for 32-bit floats (spec 5.1.1).
pub(super) const FLOAT: u32 = 5126;

/// The binary buffer and the buffer views and accessors that describe it.
#[derive(Default)]
pub(super) struct Bin {
    pub(super) data: Vec<u8>,
    pub(super) views: Vec<Value>,
    pub(super) accessors: Vec<Value>,
}

impl Bin {
    /// Append one accessor with its own buffer view at a 4-byte aligned offset (spec 3.6.2.4:
    /// offsets must be multiples of the component size; 4 covers every type written here).
    pub(super) fn accessor(
        &mut self,
        bytes: &[u8],
        component_type: u32,
        count: usize,
        ty: &str,
        target: Option<u32>,
        extra: Map<String, Value>,
    ) -> usize {
        self.data.resize(self.data.len().div_ceil(4) * 4, 0);
        let mut view = json!({
            "buffer": 0,
            "byteOffset": self.data.len(),
            "byteLength": bytes.len(),
        });
        if let Some(t) = target {
            view["target"] = json!(t);
        }
        self.data.extend_from_slice(bytes);
        self.views.push(view);
        let mut acc = json!({
            "bufferView": self.views.len() - 1,
            "componentType": component_type,
            "count": count,
            "type": ty,
        });
        if let Value::Object(m) = &mut acc {
            m.extend(extra);
        }
        self.accessors.push(acc);
        self.accessors.len() - 1
    }
}

/// Little-endian bytes of `values`, the accessor data glTF stores.
pub(super) fn f32s(values: impl IntoIterator<Item = f32>) -> Vec<u8> {
    values.into_iter().flat_map(f32::to_le_bytes).collect()
}
