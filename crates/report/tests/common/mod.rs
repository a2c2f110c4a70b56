//! Independent checkers used by the integration tests: an XML well-formedness check and a PNG header
//! reader written from the specifications, sharing no code with the crate.

#![allow(dead_code)]

/// Checks that `doc` is well-formed XML (also accepts a leading `<!DOCTYPE ...>`): every start tag is
/// closed in order, attribute values are quoted, `<` never appears in text or attribute values and
/// every `&` starts an entity reference. Returns the list of element names in document order.
pub fn check_well_formed(doc: &str) -> Result<Vec<String>, String> {
    let b = doc.as_bytes();
    let mut i = 0;
    let mut stack: Vec<String> = Vec::new();
    let mut names = Vec::new();
    let mut roots = 0;
    let err = |i: usize, m: &str| Err(format!("byte {i}: {m}"));
    while i < b.len() {
        match b[i] {
            b'<' => {
                let rest = &doc[i..];
                if rest.starts_with("<!--") {
                    match rest.find("-->") {
                        Some(e) => i += e + 3,
                        None => return err(i, "unterminated comment"),
                    }
                    continue;
                }
                if rest.starts_with("<?") || rest.starts_with("<!") {
                    if !stack.is_empty() {
                        return err(i, "declaration inside an element");
                    }
                    match rest.find('>') {
                        Some(e) => i += e + 1,
                        None => return err(i, "unterminated declaration"),
                    }
                    continue;
                }
                let closing = rest.starts_with("</");
                let mut j = i + if closing { 2 } else { 1 };
                let start = j;
                while j < b.len() && (b[j].is_ascii_alphanumeric() || b"-_:.".contains(&b[j])) {
                    j += 1;
                }
                if j == start {
                    return err(i, "tag without a name");
                }
                let name = doc[start..j].to_string();
                if closing {
                    while j < b.len() && b[j].is_ascii_whitespace() {
                        j += 1;
                    }
                    if j >= b.len() || b[j] != b'>' {
                        return err(j, "malformed end tag");
                    }
                    match stack.pop() {
                        Some(open) if open == name => {}
                        Some(open) => return err(i, &format!("</{name}> closes <{open}>")),
                        None => return err(i, &format!("</{name}> without a start tag")),
                    }
                    i = j + 1;
                    continue;
                }
                // Attributes.
                loop {
                    while j < b.len() && b[j].is_ascii_whitespace() {
                        j += 1;
                    }
                    if j >= b.len() {
                        return err(i, "unterminated start tag");
                    }
                    if b[j] == b'>' || (b[j] == b'/' && b.get(j + 1) == Some(&b'>')) {
                        break;
                    }
                    let a = j;
                    while j < b.len() && (b[j].is_ascii_alphanumeric() || b"-_:.".contains(&b[j])) {
                        j += 1;
                    }
                    if j == a || b.get(j) != Some(&b'=') {
                        return err(j, "attribute without a quoted value");
                    }
                    j += 1;
                    let q = match b.get(j) {
                        Some(&q) if q == b'"' || q == b'\'' => q,
                        _ => return err(j, "unquoted attribute value"),
                    };
                    j += 1;
                    let v = j;
                    while j < b.len() && b[j] != q {
                        j += 1;
                    }
                    if j >= b.len() {
                        return err(v, "unterminated attribute value");
                    }
                    check_text(&doc[v..j]).map_err(|m| format!("byte {v}: attribute: {m}"))?;
                    j += 1;
                }
                if stack.is_empty() {
                    roots += 1;
                }
                names.push(name.clone());
                if b[j] == b'/' {
                    i = j + 2;
                } else {
                    stack.push(name);
                    i = j + 1;
                }
            }
            _ => {
                let e = doc[i..].find('<').map_or(b.len(), |e| i + e);
                if stack.is_empty() && !doc[i..e].trim().is_empty() {
                    return err(i, "text outside the root element");
                }
                check_text(&doc[i..e]).map_err(|m| format!("byte {i}: {m}"))?;
                i = e;
            }
        }
    }
    if let Some(open) = stack.pop() {
        return Err(format!("<{open}> is never closed"));
    }
    if roots != 1 {
        return Err(format!("{roots} root elements, expected 1"));
    }
    Ok(names)
}

/// Text or attribute value: no `<`, and `&` only as `&name;` or `&#digits;` / `&#xhex;`.
fn check_text(t: &str) -> Result<(), String> {
    if t.contains('<') {
        return Err("raw '<' in text".into());
    }
    let mut rest = t;
    while let Some(p) = rest.find('&') {
        let after = &rest[p + 1..];
        let end = after.find(';').ok_or("'&' without ';'")?;
        let ent = &after[..end];
        let ok = (!ent.is_empty()
            && ent.chars().all(|c| c.is_ascii_alphanumeric())
            && !ent.starts_with('#'))
            || ent
                .strip_prefix("#x")
                .is_some_and(|h| !h.is_empty() && h.chars().all(|c| c.is_ascii_hexdigit()))
            || ent
                .strip_prefix('#')
                .is_some_and(|d| !d.is_empty() && d.chars().all(|c| c.is_ascii_digit()));
        if !ok {
            return Err(format!("bad entity &{ent};"));
        }
        rest = &after[end + 1..];
    }
    Ok(())
}

/// The 8-byte PNG signature (PNG specification, section 5.2).
pub const PNG_SIGNATURE: [u8; 8] = [0x89, b'P', b'N', b'G', 0x0d, 0x0a, 0x1a, 0x0a];

/// Width and height from the IHDR chunk, which must come first: signature (8 bytes), chunk length
/// (4, = 13), chunk type "IHDR" (4), then width and height as big-endian u32 at offsets 16 and 20.
pub fn png_size(png: &[u8]) -> Result<(u32, u32), String> {
    if png.len() < 33 {
        return Err(format!("{} bytes: too short for a PNG", png.len()));
    }
    if png[..8] != PNG_SIGNATURE {
        return Err("no PNG signature".into());
    }
    if png[8..12] != [0, 0, 0, 13] || &png[12..16] != b"IHDR" {
        return Err("first chunk is not a 13-byte IHDR".into());
    }
    let be = |o: usize| u32::from_be_bytes([png[o], png[o + 1], png[o + 2], png[o + 3]]);
    Ok((be(16), be(20)))
}

/// Decodes a PNG into 8-bit RGB rows (using the `png` crate's decoder, independent of the encoder's
/// settings), returning (width, height, pixels).
pub fn decode_rgb(png_bytes: &[u8]) -> (u32, u32, Vec<u8>) {
    let mut decoder = png::Decoder::new(png_bytes);
    decoder.set_transformations(png::Transformations::EXPAND | png::Transformations::STRIP_16);
    let mut reader = decoder.read_info().expect("PNG header");
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).expect("PNG data");
    assert_eq!(info.color_type, png::ColorType::Rgb, "expected RGB");
    buf.truncate(info.buffer_size());
    (info.width, info.height, buf)
}
