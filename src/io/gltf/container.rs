//! The byte-level layers under the glTF JSON: the GLB container (glTF 2.0 spec, section 4.4
//! "Binary glTF Layout"), `data:` URIs with base64 payloads (RFC 2397, RFC 4648 section 4) and
//! percent-encoded relative URIs (RFC 3986 section 2.1).

use std::borrow::Cow;

/// `glTF` in little-endian ASCII: the GLB magic.
pub(super) const GLB_MAGIC: u32 = 0x4654_6C67;
/// Chunk type of the JSON chunk (`JSON`).
pub(super) const CHUNK_JSON: u32 = 0x4E4F_534A;
/// Chunk type of the binary buffer chunk (`BIN\0`).
pub(super) const CHUNK_BIN: u32 = 0x004E_4942;

/// The two chunks of a GLB that matter: the JSON text and the optional BIN chunk.
pub(super) struct Glb<'a> {
    pub json: &'a [u8],
    pub bin: Option<&'a [u8]>,
}

fn u32_at(bytes: &[u8], at: usize) -> Option<u32> {
    let b = bytes.get(at..at.checked_add(4)?)?;
    Some(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
}

/// Whether `bytes` start with the GLB magic (otherwise they are read as glTF JSON).
pub(super) fn is_glb(bytes: &[u8]) -> bool {
    u32_at(bytes, 0) == Some(GLB_MAGIC)
}

/// Split a GLB into its chunks after checking the 12-byte header and every chunk length against
/// the bytes actually present (spec 4.4.2-4.4.3): the first chunk must be JSON, a BIN chunk may
/// follow, chunks of other types are skipped (spec: "client implementations MUST ignore chunks
/// with unknown types"). The error names the header field or chunk at fault.
pub(super) fn split_glb(bytes: &[u8]) -> Result<Glb<'_>, String> {
    if bytes.len() < 12 {
        return Err(format!(
            "GLB header: the file has {} bytes, fewer than the 12-byte header",
            bytes.len()
        ));
    }
    let version = u32_at(bytes, 4).unwrap_or(0);
    if version != 2 {
        return Err(format!(
            "GLB header: version {version}, only glTF 2.0 (version 2) is supported"
        ));
    }
    let length = u32_at(bytes, 8).unwrap_or(0) as usize;
    if length > bytes.len() {
        return Err(format!(
            "GLB header: declared length {length} bytes, but the file has {} (truncated?)",
            bytes.len()
        ));
    }
    if length < 12 {
        return Err(format!(
            "GLB header: declared length {length} bytes is shorter than the header"
        ));
    }
    let data = &bytes[..length];
    let mut at = 12usize;
    let mut json = None;
    let mut bin = None;
    let mut chunk = 0usize;
    while at < data.len() {
        let (Some(len), Some(ty)) = (u32_at(data, at), u32_at(data, at + 4)) else {
            return Err(format!(
                "GLB chunk {chunk}: header at byte {at} is cut off by the end of the file"
            ));
        };
        let start = at + 8;
        let end = start
            .checked_add(len as usize)
            .filter(|&e| e <= data.len())
            .ok_or_else(|| {
                format!(
                    "GLB chunk {chunk}: declared length {len} bytes at byte {start} runs past the end of the file ({} bytes)",
                    data.len()
                )
            })?;
        let body = &data[start..end];
        match (chunk, ty) {
            (0, CHUNK_JSON) => json = Some(body),
            (0, other) => {
                return Err(format!(
                    "GLB chunk 0: type 0x{other:08X}, but the first chunk must be JSON (0x4E4F534A)"
                ))
            }
            (1, CHUNK_BIN) => bin = Some(body),
            (_, CHUNK_JSON) => return Err(format!("GLB chunk {chunk}: a second JSON chunk")),
            (_, CHUNK_BIN) => {
                return Err(format!(
                    "GLB chunk {chunk}: a BIN chunk must directly follow the JSON chunk"
                ))
            }
            _ => {}
        }
        // Chunks are 4-byte aligned by the writer's padding; tolerate an unpadded last chunk.
        at = end;
        chunk += 1;
    }
    let json = json.ok_or_else(|| "GLB: no JSON chunk".to_string())?;
    Ok(Glb { json, bin })
}

/// Assemble a GLB from its JSON text and binary buffer (spec 4.4): the JSON chunk is padded
/// with spaces and the BIN chunk with zeros to multiples of 4 bytes; an empty BIN is omitted.
/// Fails only when the result would exceed the format's 4 GiB limit.
pub(super) fn compose_glb(json: &[u8], bin: &[u8]) -> Result<Vec<u8>, String> {
    let pad = |n: usize| (4 - n % 4) % 4;
    let json_len = json.len() + pad(json.len());
    let bin_len = bin.len() + pad(bin.len());
    let total = 12 + 8 + json_len + if bin.is_empty() { 0 } else { 8 + bin_len };
    let total32 = u32::try_from(total)
        .map_err(|_| format!("GLB would be {total} bytes, over the format's 4 GiB limit"))?;
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(&GLB_MAGIC.to_le_bytes());
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&total32.to_le_bytes());
    out.extend_from_slice(&(json_len as u32).to_le_bytes());
    out.extend_from_slice(&CHUNK_JSON.to_le_bytes());
    out.extend_from_slice(json);
    out.resize(out.len() + pad(json.len()), b' ');
    if !bin.is_empty() {
        out.extend_from_slice(&(bin_len as u32).to_le_bytes());
        out.extend_from_slice(&CHUNK_BIN.to_le_bytes());
        out.extend_from_slice(bin);
        out.resize(out.len() + pad(bin.len()), 0);
    }
    debug_assert_eq!(out.len(), total);
    Ok(out)
}

/// The payload of a `data:` URI (RFC 2397) whose data is base64 (RFC 4648 section 4, padding
/// optional, no whitespace), as glTF embeds buffers. `None` when `uri` is not a data URI.
pub(super) fn data_uri(uri: &str) -> Option<Result<Vec<u8>, String>> {
    let rest = uri.strip_prefix("data:")?;
    let Some((meta, payload)) = rest.split_once(',') else {
        return Some(Err("data URI without a ',' before its payload".into()));
    };
    if !meta.ends_with(";base64") {
        return Some(Err(format!(
            "data URI '{}' is not base64-encoded (glTF embeds buffers as base64)",
            truncate(uri, 40)
        )));
    }
    Some(base64_decode(payload))
}

/// Decode standard base64 (RFC 4648 section 4); the output is at most 3/4 the input's length.
pub(super) fn base64_decode(text: &str) -> Result<Vec<u8>, String> {
    let text = text.trim_end_matches('=');
    let mut out = Vec::with_capacity(text.len() / 4 * 3 + 3);
    let mut acc = 0u32;
    let mut bits = 0u32;
    for (i, c) in text.bytes().enumerate() {
        let v = match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' => 62,
            b'/' => 63,
            _ => {
                return Err(format!(
                    "base64 payload has an invalid character at position {i}"
                ))
            }
        };
        acc = (acc << 6) | u32::from(v);
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
            acc &= (1 << bits) - 1;
        }
    }
    if bits >= 6 {
        return Err("base64 payload has a dangling character at its end".into());
    }
    Ok(out)
}

/// Standard base64 encoding with padding (RFC 4648 section 4).
#[cfg(test)]
pub(super) fn base64_encode(bytes: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for c in bytes.chunks(3) {
        let n = (u32::from(c[0]) << 16)
            | (u32::from(*c.get(1).unwrap_or(&0)) << 8)
            | u32::from(*c.get(2).unwrap_or(&0));
        for k in 0..4 {
            if k <= c.len() {
                s.push(A[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

/// Decode `%XX` escapes of a relative URI reference (RFC 3986 section 2.1) into a file path
/// component; invalid escapes are kept literally (as browsers do).
pub(super) fn percent_decode(uri: &str) -> Cow<'_, str> {
    if !uri.contains('%') {
        return Cow::Borrowed(uri);
    }
    let b = uri.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' && i + 2 < b.len() {
            let hex = |c: u8| (c as char).to_digit(16);
            if let (Some(h), Some(l)) = (hex(b[i + 1]), hex(b[i + 2])) {
                out.push((h * 16 + l) as u8);
                i += 3;
                continue;
            }
        }
        out.push(b[i]);
        i += 1;
    }
    Cow::Owned(String::from_utf8_lossy(&out).into_owned())
}

/// At most `n` characters of `s`, for error messages quoting file content.
pub(super) fn truncate(s: &str, n: usize) -> String {
    if s.chars().count() <= n {
        s.to_string()
    } else {
        let t: String = s.chars().take(n).collect();
        format!("{t}...")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_round_trip_and_rfc4648_vectors() {
        // RFC 4648 section 10 test vectors.
        for (plain, enc) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(base64_encode(plain.as_bytes()), enc);
            assert_eq!(base64_decode(enc).unwrap(), plain.as_bytes());
        }
        let all: Vec<u8> = (0..=255).collect();
        assert_eq!(base64_decode(&base64_encode(&all)).unwrap(), all);
        assert!(base64_decode("Zm9v!").is_err());
        assert!(base64_decode("Z").is_err());
    }

    #[test]
    fn percent_decoding() {
        assert_eq!(percent_decode("a%20b.bin"), "a b.bin");
        assert_eq!(percent_decode("plain.bin"), "plain.bin");
        assert_eq!(percent_decode("bad%2"), "bad%2");
        assert_eq!(percent_decode("%zz"), "%zz");
    }

    #[test]
    fn glb_compose_then_split() {
        let glb = compose_glb(b"{\"a\":1}", &[1, 2, 3, 4, 5]).unwrap();
        assert_eq!(glb.len() % 4, 0);
        let g = split_glb(&glb).unwrap();
        assert_eq!(g.json, b"{\"a\":1} ");
        assert_eq!(g.bin.unwrap(), &[1, 2, 3, 4, 5, 0, 0, 0]);
        // Declared length larger than the data.
        assert!(split_glb(&glb[..glb.len() - 4]).is_err());
    }
}
