//! The `fmuResourceLocation` URI as a directory path.
//!
//! Accepted: `file:///abs/dir`, `file:/abs/dir`, `file://localhost/abs/dir`,
//! percent-encoded characters, with or without a trailing slash, and (as
//! some importers send) a plain absolute path.

use std::path::PathBuf;

/// Decodes `%XX` escapes.
fn percent_decode(s: &str) -> Result<String, String> {
    let bytes = s.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = s.get(i + 1..i + 3).ok_or_else(|| format!("truncated percent escape in {s:?}"))?;
            let v = u8::from_str_radix(hex, 16).map_err(|_| format!("invalid percent escape %{hex} in {s:?}"))?;
            out.push(v);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8(out).map_err(|_| format!("resource location {s:?} does not decode to UTF-8"))
}

pub fn resource_dir(location: &str) -> Result<PathBuf, String> {
    let path = if let Some(rest) = location.strip_prefix("file://") {
        // file://host/path: only an empty host or localhost is local.
        if let Some(p) = rest.strip_prefix("localhost/") {
            format!("/{p}")
        } else if rest.starts_with('/') {
            rest.to_string()
        } else {
            return Err(format!("resource location {location:?} names a remote host; only local file URIs are supported"));
        }
    } else if let Some(rest) = location.strip_prefix("file:") {
        rest.to_string()
    } else if location.starts_with('/') {
        location.to_string()
    } else {
        return Err(format!("resource location {location:?} is not a file URI (expected file:///path/to/resources)"));
    };
    let decoded = percent_decode(&path)?;
    Ok(PathBuf::from(decoded.trim_end_matches('/')))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_common_form() {
        let want = PathBuf::from("/tmp/my fmu/resources");
        for s in [
            "file:///tmp/my%20fmu/resources",
            "file:///tmp/my%20fmu/resources/",
            "file:/tmp/my%20fmu/resources",
            "file://localhost/tmp/my%20fmu/resources",
            "file:///tmp/my fmu/resources",
            "/tmp/my fmu/resources/",
        ] {
            assert_eq!(resource_dir(s).unwrap(), want, "{s}");
        }
        assert!(resource_dir("file://server/share").is_err());
        assert!(resource_dir("http://x/y").is_err());
        assert!(resource_dir("file:///a%2").is_err());
    }
}
