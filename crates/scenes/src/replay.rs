//! A [`Recording`] as one self-contained HTML page: three.js (from npm, read from its installed
//! folder and inlined), the viewer (`assets/replay/`) and the recording (base64 columns) in one
//! file that opens offline, with no server.
//!
//! The page draws every geom of the recording (capsules, spheres, boxes, cylinders, ellipsoids,
//! the floor) in 3-D, plays, pauses, scrubs and changes speed, orbits a camera that follows the
//! pelvis, draws the reference ghost translucent beside the body, colours a timeline strip by
//! the active skill and overlays the terms and the phase. `window.__replay` exposes
//! `{frame, frames, playing, drawn, ready}` for tests.

use std::path::{Path, PathBuf};

use crate::error::{Result, SceneError};
use crate::record::{POSE, Recording};

const VIEWER_JS: &str = include_str!("../assets/replay/replay.js");
const VIEWER_CSS: &str = include_str!("../assets/replay/replay.css");

/// The three.js build files the page inlines, in `node_modules/three/build`.
const THREE_FILES: [&str; 2] = ["three.core.js", "three.module.js"];

/// The folder `scripts/setup.sh` installs the page's npm packages into, relative to the
/// repository root.
pub const WEB_DIR: &str = "crates/scenes/web";

/// three.js's build folder under a web folder (`<web>/node_modules/three/build`).
pub fn three_build_dir(web: &Path) -> PathBuf {
    web.join("node_modules/three/build")
}

/// Reads three.js's module build from `build_dir`; a missing file says to run setup.
fn read_three(build_dir: &Path) -> Result<[String; 2]> {
    let read = |name: &str| {
        let path = build_dir.join(name);
        std::fs::read_to_string(&path).map_err(|e| {
            SceneError::Usage(format!(
                "{}: {e}; the replay page inlines three.js from npm: run `bash scripts/setup.sh` \
                 (it runs `npm ci` in {WEB_DIR}), or point --web at a folder with node_modules/three",
                path.display()
            ))
        })
    };
    Ok([read(THREE_FILES[0])?, read(THREE_FILES[1])?])
}

/// Standard base64 (with padding).
pub fn base64(bytes: &[u8]) -> String {
    const T: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for c in bytes.chunks(3) {
        let n =
            (u32::from(c[0]) << 16) | (u32::from(*c.get(1).unwrap_or(&0)) << 8) | u32::from(*c.get(2).unwrap_or(&0));
        out.push(T[(n >> 18) as usize & 63] as char);
        out.push(T[(n >> 12) as usize & 63] as char);
        out.push(if c.len() > 1 { T[(n >> 6) as usize & 63] as char } else { '=' });
        out.push(if c.len() > 2 { T[n as usize & 63] as char } else { '=' });
    }
    out
}

fn b64_f32(v: impl IntoIterator<Item = f32>) -> String {
    base64(&v.into_iter().flat_map(f32::to_le_bytes).collect::<Vec<u8>>())
}

/// Makes text safe inside a `<script>` element.
fn script_safe(text: &str) -> String {
    text.replace("</script", "<\\/script").replace("<!--", "<\\!--")
}

/// The recording as the page reads it: the header plus base64 little-endian columns.
fn page_data(rec: &Recording) -> String {
    let flags: Vec<u8> = rec
        .contacts
        .iter()
        .map(|c| {
            u8::from(c.fallen)
                | u8::from(c.pelvis_on != 0) << 1
                | u8::from(c.hand_on[0] | c.hand_on[1] != 0) << 2
                | u8::from(c.character_on != 0) << 3
        })
        .collect();
    let data = serde_json::json!({
        "header": rec.header,
        "pose": POSE,
        "time": b64_f32(rec.time.iter().map(|&t| t as f32)),
        "poses": b64_f32(rec.poses.iter().copied()),
        "ghost": b64_f32(rec.ghost.iter().copied()),
        "skill": base64(&rec.skill.iter().flat_map(|s| s.to_le_bytes()).collect::<Vec<u8>>()),
        "phase": b64_f32(rec.phase.iter().copied()),
        "terms": b64_f32(rec.terms.iter().copied()),
        "flags": base64(&flags),
        "fall": base64(&rec.fall),
        // The first prop whose key geom (a chair's seat, a pedestal's top, a box) the pelvis
        // touches, + 1 (0: none), so the page can name it.
        "pelvis_on": base64(&rec.contacts.iter().map(|c| first_prop(c.pelvis_on)).collect::<Vec<u8>>()),
        // Which feet touch the floor (bit 0 left, bit 1 right); absent for format 1 files,
        // which did not record it.
        "feet": (rec.header.format >= 2).then(|| base64(
            &rec.contacts.iter().map(|c| u8::from(c.feet_on_floor[0]) | u8::from(c.feet_on_floor[1]) << 1).collect::<Vec<u8>>()
        )),
        "fall_causes": crate::fall::FallCause::ALL.map(|c| c.name()),
    });
    // `<` only occurs inside JSON strings, where \u003c reads the same.
    data.to_string().replace('<', "\\u003c")
}

/// 1 + the lowest prop index set in a contact bit set, 0 for none.
fn first_prop(bits: u64) -> u8 {
    if bits == 0 { 0 } else { (bits.trailing_zeros() + 1).min(255) as u8 }
}

fn escape_html(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

/// The replay page of `rec`, inlining three.js from `three_build` (see [`three_build_dir`]).
pub fn html(rec: &Recording, three_build: &Path) -> Result<String> {
    let [core, module] = read_three(three_build)?;
    let title = escape_html(if rec.header.title.is_empty() { "Repertoire replay" } else { &rec.header.title });
    let mut page = String::with_capacity(core.len() + module.len() + rec.poses.len() * 6 + 65_536);
    page.push_str("<!doctype html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n");
    page.push_str("<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n");
    page.push_str(&format!("<title>{title}</title>\n<style>\n{VIEWER_CSS}</style>\n</head>\n<body>\n"));
    page.push_str(&format!(
        r#"<div id="view"></div>
<div id="overlay"><div id="title">{title}</div><div id="info"></div><table id="terms"></table></div>
<div id="bar">
  <button id="play" title="play / pause (space)">❚❚</button>
  <span id="clock"></span>
  <label>speed <select id="speed"><option>0.25</option><option>0.5</option><option selected>1</option><option>2</option><option>4</option></select></label>
  <label>ghost <select id="ghostmode"><option value="beside" selected>beside</option><option value="overlay">overlay</option><option value="off">off</option></select></label>
  <label><input id="follow" type="checkbox" checked> follow</label>
  <label>view <select id="viewpreset"><option value="free" selected>free</option><option value="side">side</option><option value="front">front</option><option value="top">top</option></select></label>
</div>
<div id="timeline"><input id="scrub" type="range" min="0" max="0" value="0" step="1" title="scrub (← →)"><canvas id="strip"></canvas><div id="legend"></div></div>
<div id="error" hidden></div>
"#
    ));
    page.push_str(&format!("<script type=\"text/plain\" id=\"three-core\">{}</script>\n", script_safe(&core)));
    page.push_str(&format!("<script type=\"text/plain\" id=\"three-module\">{}</script>\n", script_safe(&module)));
    page.push_str(&format!("<script type=\"application/json\" id=\"recording\">{}</script>\n", page_data(rec)));
    page.push_str(&format!("<script type=\"module\">\n{}</script>\n</body>\n</html>\n", script_safe(VIEWER_JS)));
    Ok(page)
}

/// Writes the replay page of `rec` to `out` (atomically).
pub fn write_html(rec: &Recording, three_build: &Path, out: &Path) -> Result<()> {
    crate::record::write_atomic(out, html(rec, three_build)?.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_matches_the_rfc_examples() {
        let cases =
            [("", ""), ("f", "Zg=="), ("fo", "Zm8="), ("foo", "Zm9v"), ("foob", "Zm9vYg=="), ("fooba", "Zm9vYmE=")];
        for (plain, encoded) in cases {
            assert_eq!(base64(plain.as_bytes()), encoded);
        }
    }

    #[test]
    fn script_text_cannot_close_its_element() {
        assert_eq!(script_safe("a</script>b<!--c"), "a<\\/script>b<\\!--c");
    }
}
