//! User text in messages: characters that a terminal does not show (a byte-order mark, a
//! zero-width space, a right-to-left override) or that it acts on (NUL, ESC and the other
//! control characters) are written as escapes (`\u{feff}`, `\x1b`) and named, so that a
//! message quoting a model or a data file says what is there, and quoting a file cannot
//! move the cursor or recolour the terminal.

/// What an invisible or control character is, in words; `None` for a character that
/// shows as itself (tabs, line ends and ordinary spaces included).
pub fn invisible_name(c: char) -> Option<&'static str> {
    Some(match c {
        '\t' | '\n' | ' ' => return None,
        '\0' => "a NUL byte",
        '\x1b' => "an escape character (ESC)",
        '\r' => "a carriage return",
        '\x7f' => "a delete character (DEL)",
        '\u{feff}' => "a byte-order mark",
        '\u{fffe}' => "a reversed byte-order mark (UTF-16 text read as UTF-8?)",
        '\u{200b}' => "a zero-width space",
        '\u{200c}' => "a zero-width non-joiner",
        '\u{200d}' => "a zero-width joiner",
        '\u{2060}' => "a word joiner",
        '\u{00ad}' => "a soft hyphen",
        '\u{00a0}' => "a no-break space",
        '\u{200e}' => "a left-to-right mark",
        '\u{200f}' => "a right-to-left mark",
        '\u{061c}' => "an Arabic letter mark",
        '\u{202a}'..='\u{202e}' => "a bidirectional embedding or override",
        '\u{2066}'..='\u{2069}' => "a bidirectional isolate",
        '\u{2028}' => "a line separator",
        '\u{2029}' => "a paragraph separator",
        '\u{2061}'..='\u{2064}' | '\u{206a}'..='\u{206f}' => "an invisible format character",
        c if c.is_control() => "a control character",
        _ => return None,
    })
}

/// `s` with every character that [`invisible_name`] names written as an escape: `\x1b`
/// for ASCII control characters, `\u{feff}` for the others. Other text is unchanged.
pub fn escape(s: &str) -> String {
    if !s.chars().any(|c| invisible_name(c).is_some()) {
        return s.to_string();
    }
    let mut out = String::with_capacity(s.len() + 8);
    for c in s.chars() {
        if invisible_name(c).is_some() {
            out.push_str(&escape_char(c));
        } else {
            out.push(c);
        }
    }
    out
}

/// One character as an escape (`\x1b`, `\u{feff}`).
pub fn escape_char(c: char) -> String {
    if (c as u32) < 0x80 {
        format!("\\x{:02x}", c as u32)
    } else {
        format!("\\u{{{:x}}}", c as u32)
    }
}

/// What the invisible characters of `s` are, e.g. "`\u{200b}` is a zero-width space";
/// `None` when `s` has none. Each distinct character is named once, in order.
pub fn describe_invisibles(s: &str) -> Option<String> {
    let mut seen: Vec<char> = Vec::new();
    for c in s.chars() {
        if invisible_name(c).is_some() && !seen.contains(&c) {
            seen.push(c);
        }
    }
    if seen.is_empty() {
        return None;
    }
    Some(
        seen.iter()
            .map(|&c| {
                format!(
                    "`{}` is {}",
                    escape_char(c),
                    invisible_name(c).unwrap_or("a control character")
                )
            })
            .collect::<Vec<_>>()
            .join(", "),
    )
}

/// `s` in backquotes with its invisible characters escaped, followed by what they are:
/// "`m.x\u{200b}` (`\u{200b}` is a zero-width space)".
pub fn quote(s: &str) -> String {
    match describe_invisibles(s) {
        Some(d) => format!("`{}` ({d})", escape(s)),
        None => format!("`{s}`"),
    }
}

/// `s` with each invisible or control character (other than tab, line feed and carriage
/// return) replaced by a visible one of the same length in UTF-8 (`?` for one byte, `¤` for
/// two, `�` for three), so that byte offsets into `s` stay valid: for showing a source
/// excerpt on a terminal.
pub fn visible(s: &str) -> String {
    s.chars()
        .map(|c| match c {
            '\t' | '\n' | '\r' => c,
            c if invisible_name(c).is_some() => match c.len_utf8() {
                1 => '?',
                2 => '¤',
                _ => '\u{fffd}',
            },
            c => c,
        })
        .collect()
}

/// The encoding of text that is UTF-16 rather than UTF-8, told from a byte-order mark or
/// from NUL bytes at every other position of the first line (ASCII text in UTF-16).
pub fn utf16_kind(bytes: &[u8]) -> Option<&'static str> {
    match bytes {
        [0xff, 0xfe, ..] => return Some("UTF-16 (little-endian, with a byte-order mark)"),
        [0xfe, 0xff, ..] => return Some("UTF-16 (big-endian, with a byte-order mark)"),
        _ => {}
    }
    let head = &bytes[..bytes.len().min(64) & !1];
    if head.len() < 8 {
        return None;
    }
    let zeros = |k: usize| head.iter().skip(k).step_by(2).filter(|&&b| b == 0).count();
    let half = head.len() / 2;
    if zeros(1) == half && zeros(0) == 0 {
        Some("UTF-16 (little-endian)")
    } else if zeros(0) == half && zeros(1) == 0 {
        Some("UTF-16 (big-endian)")
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn invisible_characters_are_escaped_and_named() {
        assert_eq!(escape("a\u{feff}b\x1bc"), "a\\u{feff}b\\x1bc");
        assert_eq!(escape("m.x, u\t1.5"), "m.x, u\t1.5");
        assert_eq!(
            quote("m.x\u{200b}"),
            "`m.x\\u{200b}` (`\\u{200b}` is a zero-width space)"
        );
        assert_eq!(
            describe_invisibles("\u{202e}x\0\u{202e}").as_deref(),
            Some("`\\u{202e}` is a bidirectional embedding or override, `\\x00` is a NUL byte")
        );
        assert_eq!(quote("é"), "`é`");
    }

    #[test]
    fn visible_text_keeps_byte_offsets() {
        let s = "a\u{feff}b\x1b[31mc\u{a0}d\n";
        let v = visible(s);
        assert_eq!(v.len(), s.len());
        assert_eq!(v, "a\u{fffd}b?[31mc¤d\n");
    }

    #[test]
    fn utf16_is_recognised() {
        let le: Vec<u8> = "t,m.x,u\n"
            .encode_utf16()
            .flat_map(|u| u.to_le_bytes())
            .collect();
        let be: Vec<u8> = "t,m.x,u\n"
            .encode_utf16()
            .flat_map(|u| u.to_be_bytes())
            .collect();
        assert_eq!(utf16_kind(&le), Some("UTF-16 (little-endian)"));
        assert_eq!(utf16_kind(&be), Some("UTF-16 (big-endian)"));
        assert!(utf16_kind(&[0xff, 0xfe, b'm', 0]).is_some());
        assert_eq!(utf16_kind(b"t,m.x,u\n0,1,2\n"), None);
        assert_eq!(utf16_kind(b""), None);
    }
}
