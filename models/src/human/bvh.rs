//! A small, strict BVH reader: hierarchy (joints, offsets, channels, end sites) and motion values.
//!
//! Errors carry the line number and say what was expected; nothing here panics on bad input.

use std::collections::HashMap;

use nalgebra::Vector3;

use super::error::HumanImportError;

/// Most channels a joint may declare (6 is the usual maximum: three positions, three rotations).
pub const MAX_CHANNELS_PER_JOINT: usize = 12;

/// Most joints a file may have, and most `End Site` blocks: mocap skeletons have a few hundred at most.
/// Every joint and end site under a foot is posed in every frame to find the floor, so their number
/// times the frame count is the import's work.
pub const MAX_JOINTS: usize = 1000;

/// Range of `Frame Time:` accepted, seconds: 1000 frames per second down to one frame per 10 s.
/// Outside it the clip's timing is not mocap timing (`Frame Time: 1e-9` would squeeze a clip into
/// one frame when resampled).
pub const FRAME_TIME_RANGE: (f32, f32) = (1e-3, 10.0);

/// Longest clip accepted, seconds (`Frames:` × `Frame Time:`): two hours. Checked once the motion
/// lines are read (their storage is bounded by the file's size), before anything is made of them: a
/// clip is resampled to the project's frame rate after import, so 100,000 frames of `Frame Time: 10`
/// (a 13 MB file) would otherwise become 30 million frames, many gigabytes.
pub const MAX_CLIP_SECONDS: f64 = 7200.0;

/// A coordinate axis of the file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Axis {
    X,
    Y,
    Z,
}

impl Axis {
    /// 0, 1 or 2.
    pub fn index(self) -> usize {
        self as usize
    }
}

/// One animation channel of a joint.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Channel {
    Position(Axis),
    Rotation(Axis),
}

/// A joint of the BVH hierarchy.
#[derive(Clone, Debug)]
pub struct BvhJoint {
    pub name: String,
    pub parent: Option<usize>,
    pub offset: Vector3<f32>,
    /// Channels in file order; rotations compose in this order (R = R_first · R_second · R_third).
    pub channels: Vec<Channel>,
    /// Index of this joint's first value within a frame line.
    pub first_channel: usize,
    /// Offsets of `End Site` children.
    pub end_sites: Vec<Vector3<f32>>,
    /// Line of the `ROOT`/`JOINT` keyword.
    pub line: usize,
}

/// A parsed BVH file. Joints are in file order, so parents come before their children.
#[derive(Clone, Debug)]
pub struct Bvh {
    pub joints: Vec<BvhJoint>,
    /// Values per frame line.
    pub channel_count: usize,
    /// Seconds per frame.
    pub frame_time: f32,
    pub frame_count: usize,
    /// `frame_count × channel_count` values, frame-major.
    pub values: Vec<f32>,
}

impl Bvh {
    /// The values of frame `i`.
    pub fn frame(&self, i: usize) -> &[f32] {
        &self.values[i * self.channel_count..(i + 1) * self.channel_count]
    }

    /// Parse BVH text; `file` names the source in error messages.
    pub fn parse(text: &str, file: &str) -> Result<Bvh, HumanImportError> {
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        // Lines may end in CR alone (old Mac files), which `str::lines` does not split at (CR LF it does).
        let lone_cr = text.contains('\r') && text.as_bytes().iter().enumerate().any(|(i, &b)| b == b'\r' && text.as_bytes().get(i + 1) != Some(&b'\n'));
        let text: std::borrow::Cow<str> = if lone_cr {
            text.replace("\r\n", "\n").replace('\r', "\n").into()
        } else {
            text.into()
        };
        let text = &*text;
        let err = |line: usize, message: String| HumanImportError::Parse {
            file: file.to_string(),
            line,
            message,
        };

        // Split at the MOTION keyword (first token of its line).
        let mut motion_line = None;
        let mut lines = text.lines().enumerate();
        let mut tokens: Vec<(&str, usize)> = Vec::new();
        for (i, line) in lines.by_ref() {
            let first = line.split_ascii_whitespace().next();
            if first.is_some_and(|t| t.eq_ignore_ascii_case("MOTION")) {
                motion_line = Some(i + 1);
                break;
            }
            for word in line.split_ascii_whitespace() {
                split_braces(word, i + 1, &mut tokens);
            }
        }
        let last_line = text.lines().count().max(1);
        let mut parser = HierarchyParser {
            tokens: &tokens,
            pos: 0,
            joints: Vec::new(),
            names: HashMap::new(),
            channels: 0,
            end_sites: 0,
            file,
        };
        match tokens.first() {
            Some((t, _)) if t.eq_ignore_ascii_case("HIERARCHY") => parser.pos = 1,
            Some((t, l)) => return Err(err(*l, format!("expected `HIERARCHY`, found `{t}`"))),
            None => {
                let line = motion_line.unwrap_or(last_line);
                return Err(err(line, "missing HIERARCHY section".into()));
            }
        }
        let end_line = motion_line.unwrap_or(last_line);
        parser.parse_roots(end_line)?;
        let Some(motion_line) = motion_line else {
            return Err(err(
                last_line,
                "missing MOTION section (file ends after the hierarchy)".into(),
            ));
        };
        let HierarchyParser {
            joints,
            channels: channel_count,
            ..
        } = parser;

        // Header: `Frames: N` and `Frame Time: t` (possibly with tabs, possibly blank lines between).
        let mut header = lines.by_ref().filter(|(_, l)| !l.trim().is_empty());
        let (frames_line, frame_count) = match header.next() {
            Some((i, l)) => {
                let rest = strip_keyword(l, &["Frames:"]).ok_or_else(|| {
                    err(
                        i + 1,
                        format!(
                            "expected `Frames: <count>` after MOTION, found `{}`",
                            l.trim()
                        ),
                    )
                })?;
                let n = rest.trim().parse::<usize>().map_err(|_| {
                    err(
                        i + 1,
                        format!(
                            "`Frames:` count `{}` is not a non-negative integer",
                            rest.trim()
                        ),
                    )
                })?;
                (i + 1, n)
            }
            None => {
                return Err(err(
                    motion_line,
                    "MOTION section has no `Frames:` line".into(),
                ));
            }
        };
        let (frame_time_line, frame_time_text, frame_time) = match header.next() {
            Some((i, l)) => {
                let rest = strip_keyword(l, &["Frame Time:", "FrameTime:"]).ok_or_else(|| {
                    err(
                        i + 1,
                        format!("expected `Frame Time: <seconds>`, found `{}`", l.trim()),
                    )
                })?;
                let t = rest
                    .trim()
                    .parse::<f32>()
                    .ok()
                    .filter(|t| t.is_finite() && *t > 0.0);
                let t = t.ok_or_else(|| {
                    err(
                        i + 1,
                        format!("`Frame Time:` `{}` is not a positive number", rest.trim()),
                    )
                })?;
                let (lo, hi) = FRAME_TIME_RANGE;
                if !(lo..=hi).contains(&t) {
                    return Err(err(
                        i + 1,
                        format!(
                            "`Frame Time: {}` is {:.4} frames per second; expected {lo} to {hi} seconds per frame \
                             (1000 down to 0.1 frames per second)",
                            rest.trim(),
                            1.0 / t
                        ),
                    ));
                }
                (i + 1, rest.trim(), t)
            }
            None => {
                return Err(err(
                    frames_line,
                    "MOTION section has no `Frame Time:` line".into(),
                ));
            }
        };
        if frame_count == 0 {
            return Err(err(
                frames_line,
                "`Frames: 0`: the clip has no motion".into(),
            ));
        }

        // The header alone never sizes an allocation: a value takes at least two bytes of text.
        let declared = frame_count.saturating_mul(channel_count);
        let mut values = Vec::with_capacity(declared.min(text.len() / 2 + 1));
        let mut found = 0;
        let mut last = frames_line + 1;
        for (i, line) in lines {
            if found == frame_count {
                if line.trim().is_empty() {
                    continue;
                }
                return Err(err(
                    i + 1,
                    format!(
                        "more motion lines than `Frames: {frame_count}` declares (line {} is frame {}); \
                         correct the `Frames:` count",
                        i + 1,
                        frame_count + 1
                    ),
                ));
            }
            last = i + 1;
            let before = values.len();
            for (k, tok) in line.split_ascii_whitespace().enumerate() {
                if k >= channel_count {
                    let n = line.split_ascii_whitespace().count();
                    return Err(err(
                        i + 1,
                        format!("expected {channel_count} values, found {n}"),
                    ));
                }
                match tok.parse::<f32>() {
                    Ok(v) if v.is_finite() => values.push(v),
                    Ok(_) => {
                        return Err(err(i + 1, format!("value {} `{tok}` is not finite", k + 1)));
                    }
                    Err(_) => {
                        return Err(err(
                            i + 1,
                            format!("value {} `{tok}` is not a number", k + 1),
                        ));
                    }
                }
            }
            let n = values.len() - before;
            if n == 0 {
                continue; // blank line
            }
            if n != channel_count {
                return Err(err(
                    i + 1,
                    format!("expected {channel_count} values, found {n}"),
                ));
            }
            found += 1;
        }
        if found < frame_count {
            return Err(HumanImportError::Truncated {
                file: file.to_string(),
                line: last,
                declared: frame_count,
                found,
            });
        }
        // The frames are all there (a header that lies about their count is said to, above); whatever
        // is made of them later stays bounded.
        let seconds = frame_count as f64 * f64::from(frame_time);
        if seconds > MAX_CLIP_SECONDS {
            return Err(err(
                frame_time_line,
                format!(
                    "`Frames: {frame_count}` at `Frame Time: {frame_time_text}` is {seconds:.0} s of motion; \
                     clips of at most {MAX_CLIP_SECONDS} s (2 hours) are read: split the clip"
                ),
            ));
        }
        Ok(Bvh {
            joints,
            channel_count,
            frame_time,
            frame_count,
            values,
        })
    }
}

/// `rest` of `line` after one of `keywords` (case-insensitive; whitespace inside the keyword may vary).
fn strip_keyword<'a>(line: &'a str, keywords: &[&str]) -> Option<&'a str> {
    let line = line.trim_start();
    for kw in keywords {
        // Compare ignoring whitespace runs, e.g. "Frame  Time:" or "Frame\tTime:".
        let mut rest = line;
        let mut ok = true;
        for (n, part) in kw.split(' ').enumerate() {
            if n > 0 {
                let trimmed = rest.trim_start();
                if trimmed.len() == rest.len() {
                    ok = false;
                    break;
                }
                rest = trimmed;
            }
            // Bytes, not chars: the line may hold any UTF-8 after a keyword's ASCII prefix.
            if rest.as_bytes().get(..part.len()).is_some_and(|b| b.eq_ignore_ascii_case(part.as_bytes())) {
                rest = &rest[part.len()..];
            } else {
                ok = false;
                break;
            }
        }
        if ok {
            return Some(rest);
        }
    }
    None
}

/// Push `word` as tokens, with `{` and `}` split off as tokens of their own.
fn split_braces<'a>(word: &'a str, line: usize, out: &mut Vec<(&'a str, usize)>) {
    let mut start = 0;
    for (i, c) in word.char_indices() {
        if c == '{' || c == '}' {
            if i > start {
                out.push((&word[start..i], line));
            }
            out.push((&word[i..i + 1], line));
            start = i + 1;
        }
    }
    if start < word.len() {
        out.push((&word[start..], line));
    }
}

struct HierarchyParser<'t, 'a> {
    tokens: &'t [(&'a str, usize)],
    pos: usize,
    joints: Vec<BvhJoint>,
    /// Index of each joint by name, to refuse duplicates.
    names: HashMap<String, usize>,
    channels: usize,
    /// `End Site` blocks read so far.
    end_sites: usize,
    file: &'t str,
}

impl<'a> HierarchyParser<'_, 'a> {
    fn err(&self, line: usize, message: String) -> HumanImportError {
        HumanImportError::Parse {
            file: self.file.to_string(),
            line,
            message,
        }
    }

    fn next(&mut self, end_line: usize, what: &str) -> Result<(&'a str, usize), HumanImportError> {
        match self.tokens.get(self.pos) {
            Some(&(t, l)) => {
                self.pos += 1;
                Ok((t, l))
            }
            None => Err(self.err(
                end_line,
                format!("unexpected end of hierarchy: expected {what}"),
            )),
        }
    }

    fn number(&mut self, end_line: usize, what: &str) -> Result<f32, HumanImportError> {
        let (t, l) = self.next(end_line, what)?;
        match t.parse::<f32>() {
            Ok(v) if v.is_finite() => Ok(v),
            _ => Err(self.err(l, format!("expected {what}, found `{t}`"))),
        }
    }

    fn parse_roots(&mut self, end_line: usize) -> Result<(), HumanImportError> {
        while self.pos < self.tokens.len() {
            let (t, l) = self.next(end_line, "ROOT")?;
            if t.eq_ignore_ascii_case("ROOT") {
                self.parse_joint(None, l, end_line)?;
            } else if t == "}" {
                return Err(self.err(l, "unbalanced braces: `}` without a matching `{`".into()));
            } else if t.eq_ignore_ascii_case("MOTION") {
                return Err(self.err(l, "`MOTION` must begin a line of its own".into()));
            } else {
                return Err(self.err(l, format!("expected `ROOT` or `MOTION`, found `{t}`")));
            }
        }
        if self.joints.is_empty() {
            return Err(self.err(end_line, "the hierarchy has no ROOT joint".into()));
        }
        Ok(())
    }

    /// The joint name after a `ROOT`/`JOINT` keyword at `line`: every token on that line up to `{`
    /// (names may contain spaces).
    fn joint_name(&mut self, line: usize) -> Result<String, HumanImportError> {
        let mut name_parts = Vec::new();
        while let Some(&(t, l)) = self.tokens.get(self.pos) {
            if l != line || t == "{" || t == "}" {
                break;
            }
            name_parts.push(t);
            self.pos += 1;
        }
        if name_parts.is_empty() {
            return Err(self.err(line, "joint without a name".into()));
        }
        Ok(name_parts.join(" "))
    }

    /// Opens a joint after its `ROOT`/`JOINT` keyword at `line`: reads its name and `{` and pushes it.
    fn open_joint(
        &mut self,
        parent: Option<usize>,
        line: usize,
        end_line: usize,
        open: &mut Vec<OpenJoint>,
    ) -> Result<(), HumanImportError> {
        let name = self.joint_name(line)?;
        if self.joints.len() == MAX_JOINTS {
            return Err(self.err(
                line,
                format!("joint `{name}` is one more than the {MAX_JOINTS} joints a file may have"),
            ));
        }
        if let Some(&first) = self.names.get(&name) {
            return Err(self.err(
                line,
                format!(
                    "duplicate joint name `{name}` (first defined at line {}); joint names must be unique",
                    self.joints[first].line
                ),
            ));
        }
        self.names.insert(name.clone(), self.joints.len());
        let (t, l) = self.next(end_line, "`{`")?;
        if t != "{" {
            return Err(self.err(
                l,
                format!("expected `{{` after joint `{name}`, found `{t}`"),
            ));
        }
        open.push(OpenJoint {
            index: self.joints.len(),
            has_offset: false,
        });
        self.joints.push(BvhJoint {
            name,
            parent,
            offset: Vector3::zeros(),
            channels: Vec::new(),
            first_channel: self.channels,
            end_sites: Vec::new(),
            line,
        });
        Ok(())
    }

    /// Parse a joint (and everything below it) after its `ROOT` keyword at `line`. Iterative, with
    /// an explicit stack of open joints: the file decides the depth, so it must not decide the depth
    /// of the call stack.
    fn parse_joint(
        &mut self,
        parent: Option<usize>,
        line: usize,
        end_line: usize,
    ) -> Result<(), HumanImportError> {
        let mut open: Vec<OpenJoint> = Vec::new();
        self.open_joint(parent, line, end_line, &mut open)?;
        while let Some(&OpenJoint { index, .. }) = open.last() {
            let Some(&(t, l)) = self.tokens.get(self.pos) else {
                let j = &self.joints[index];
                return Err(self.err(
                    end_line,
                    format!(
                        "unbalanced braces: `{{` of joint `{}` (line {}) is never closed",
                        j.name, j.line
                    ),
                ));
            };
            self.pos += 1;
            let name = self.joints[index].name.clone();
            if t == "}" {
                let closed = open.pop().expect("non-empty");
                if !closed.has_offset {
                    let j = &self.joints[closed.index];
                    return Err(self.err(j.line, format!("joint `{}` has no OFFSET", j.name)));
                }
            } else if t.eq_ignore_ascii_case("OFFSET") {
                let mut o = Vector3::zeros();
                for k in 0..3 {
                    o[k] = self.number(end_line, "an OFFSET coordinate")?;
                }
                self.joints[index].offset = o;
                if let Some(top) = open.last_mut() {
                    top.has_offset = true;
                }
            } else if t.eq_ignore_ascii_case("CHANNELS") {
                let (n, nl) = self.next(end_line, "the channel count")?;
                let n: usize = n
                    .parse()
                    .ok()
                    .filter(|&n| n <= MAX_CHANNELS_PER_JOINT)
                    .ok_or_else(|| {
                        self.err(
                            nl,
                            format!(
                                "channel count `{n}` of joint `{name}` is not an integer from 0 to {MAX_CHANNELS_PER_JOINT}"
                            ),
                        )
                    })?;
                if !self.joints[index].channels.is_empty() {
                    return Err(self.err(nl, format!("joint `{name}` has two CHANNELS lines")));
                }
                for _ in 0..n {
                    let (c, cl) = self.next(end_line, "a channel name")?;
                    let ch = parse_channel(c).ok_or_else(|| {
                        self.err(cl, format!("unknown channel `{c}` in joint `{name}`"))
                    })?;
                    self.joints[index].channels.push(ch);
                }
                self.joints[index].first_channel = self.channels;
                self.channels += n;
            } else if t.eq_ignore_ascii_case("JOINT") {
                self.open_joint(Some(index), l, end_line, &mut open)?;
            } else if t.eq_ignore_ascii_case("End") {
                if self.end_sites == MAX_JOINTS {
                    return Err(self.err(
                        l,
                        format!("`End Site` in joint `{name}` is one more than the {MAX_JOINTS} a file may have"),
                    ));
                }
                self.end_sites += 1;
                let (s, sl) = self.next(end_line, "`Site`")?;
                if !s.eq_ignore_ascii_case("Site") {
                    return Err(self.err(sl, format!("expected `End Site`, found `End {s}`")));
                }
                // Some exporters name end sites; skip anything up to the brace on that line.
                while self
                    .tokens
                    .get(self.pos)
                    .is_some_and(|&(t, tl)| tl == sl && t != "{")
                {
                    self.pos += 1;
                }
                let (b, bl) = self.next(end_line, "`{`")?;
                if b != "{" {
                    return Err(
                        self.err(bl, format!("expected `{{` after `End Site`, found `{b}`"))
                    );
                }
                let mut o = Vector3::zeros();
                let (k, kl) = self.next(end_line, "OFFSET")?;
                if !k.eq_ignore_ascii_case("OFFSET") {
                    return Err(self.err(kl, format!("expected OFFSET in `End Site`, found `{k}`")));
                }
                for c in 0..3 {
                    o[c] = self.number(end_line, "an OFFSET coordinate")?;
                }
                let (b, bl) = self.next(end_line, "`}`")?;
                if b != "}" {
                    return Err(
                        self.err(bl, format!("expected `}}` closing `End Site`, found `{b}`"))
                    );
                }
                self.joints[index].end_sites.push(o);
            } else if t == "{" {
                return Err(self.err(
                    l,
                    format!("unbalanced braces: unexpected `{{` in joint `{name}`"),
                ));
            } else {
                return Err(self.err(l, format!("unexpected `{t}` in joint `{name}`")));
            }
        }
        Ok(())
    }
}

/// A joint whose `{` is open while its block is read.
struct OpenJoint {
    index: usize,
    has_offset: bool,
}

fn parse_channel(c: &str) -> Option<Channel> {
    let lower = c.to_ascii_lowercase();
    let axis = match lower.as_bytes().first()? {
        b'x' => Axis::X,
        b'y' => Axis::Y,
        b'z' => Axis::Z,
        _ => return None,
    };
    match &lower[1..] {
        "position" => Some(Channel::Position(axis)),
        "rotation" => Some(Channel::Rotation(axis)),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SMALL: &str = "HIERARCHY\nROOT Hips\n{\n OFFSET 0 1 0\n CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n JOINT Left Leg{\n  OFFSET 0.1 -0.5 0\n  CHANNELS 3 Zrotation Xrotation Yrotation\n  End Site\n  {\n   OFFSET 0 -0.4 0\n  }\n }\n}\nMOTION\nFrames:\t2\nFrame Time: 0.5\n0 1 0 0 0 0 1 2 3\n\n0 1 0 0 0 0 1 2 3e-1\n";

    #[test]
    fn parses_a_small_file() {
        let b = Bvh::parse(SMALL, "small.bvh").unwrap();
        assert_eq!(b.joints.len(), 2);
        assert_eq!(b.joints[1].name, "Left Leg");
        assert_eq!(b.joints[1].parent, Some(0));
        assert_eq!(b.joints[1].first_channel, 6);
        assert_eq!(b.joints[1].end_sites.len(), 1);
        assert_eq!(b.channel_count, 9);
        assert_eq!(b.frame_count, 2);
        assert!((b.frame(1)[8] - 0.3).abs() < 1e-6);
        assert_eq!(b.frame_time, 0.5);
    }

    fn parse_err(text: &str) -> String {
        Bvh::parse(text, "bad.bvh").unwrap_err().to_string()
    }

    /// What an error quotes is printable: macOS's `._walk.bvh` (binary) put NUL bytes on the terminal.
    #[test]
    fn a_binary_file_is_quoted_with_its_control_characters_escaped() {
        let e = parse_err("\0\u{5}\u{16}\u{7}\0\u{2}\0\0Mac OS X  \u{1b}[2J\n");
        assert_eq!(e, "bad.bvh, line 1: expected `HIERARCHY`, found `\\u{0}\\u{5}\\u{16}\\u{7}\\u{0}\\u{2}\\u{0}\\u{0}Mac`");
        let e = parse_err("HIERARCHY\nROOT\tHips\u{1b}[2J {\n");
        assert!(!e.chars().any(char::is_control) && e.contains("\\u{1b}"), "{e}");
    }

    /// Lines ending in CR LF or CR alone (old Mac files) read as with LF; CR alone once made the file
    /// one line, refused as "expected `ROOT` or `MOTION`, found `MOTION`".
    #[test]
    fn lines_may_end_in_cr_lf_or_cr_alone() {
        let want = Bvh::parse(SMALL, "small.bvh").unwrap();
        for end in ["\r\n", "\r"] {
            let b = Bvh::parse(&SMALL.replace('\n', end), "small.bvh").unwrap();
            assert_eq!((b.joints.len(), b.frame_count, &b.values), (want.joints.len(), want.frame_count, &want.values), "{end:?}");
            // Errors keep their lines.
            let e = parse_err(&SMALL.replace("OFFSET 0 -0.4 0", "OFFSET 0 inf 0").replace('\n', end));
            assert!(e.contains("line 11: expected an OFFSET coordinate, found `inf`"), "{e}");
        }
        let e = parse_err(&SMALL.replace("}\nMOTION", "} MOTION"));
        assert!(e.contains("line 14: `MOTION` must begin a line of its own"), "{e}");
    }

    #[test]
    fn a_keyword_cut_inside_a_multibyte_character_is_an_error_not_a_panic() {
        // Found by fuzzing: "Frames" + 'é' puts a char boundary inside the 7 bytes "Frames:" is compared
        // with.
        let e = parse_err(&SMALL.replace("Frames:\t2", "Frames\u{e9} 2"));
        assert!(e.contains("bad.bvh") && e.contains("expected `Frames: <count>`"), "{e}");
        let e = parse_err(&SMALL.replace("Frame Time:", "Frame Time\u{e9}"));
        assert!(e.contains("bad.bvh") && e.contains("Frame Time"), "{e}");
    }

    #[test]
    fn reports_bad_input_with_line_numbers() {
        let e = parse_err(&SMALL.replace("1 2 3e-1", "1 2"));
        assert!(
            e.contains("bad.bvh, line 20: expected 9 values, found 8"),
            "{e}"
        );
        let e = parse_err(&SMALL.replace("1 2 3e-1", "1 2 abc"));
        assert!(
            e.contains("line 20") && e.contains("`abc` is not a number"),
            "{e}"
        );
        let e = parse_err(&SMALL.replace("Frames:\t2", "Frames: 3"));
        assert!(
            e.contains("truncated") && e.contains("Frames: 3") && e.contains("only 2"),
            "{e}"
        );
        let e = parse_err(&SMALL.replace("MOTION", "MOTIONS"));
        assert!(e.contains("bad.bvh") && e.contains("MOTIONS"), "{e}");
        let e = parse_err(SMALL.split("MOTION").next().unwrap());
        assert!(e.contains("missing MOTION"), "{e}");
        let e = parse_err(&SMALL.replacen(" }\n}\n", " }\n", 1));
        assert!(e.contains("unbalanced braces") && e.contains("Hips"), "{e}");
        let e = parse_err(&SMALL.replace("HIERARCHY", ""));
        assert!(e.contains("expected `HIERARCHY`"), "{e}");
        let e = parse_err(&SMALL.replace(
            "Zrotation Xrotation Yrotation\n  End",
            "Zrotation Xrotation Wrotation\n  End",
        ));
        assert!(e.contains("line 8") && e.contains("Wrotation"), "{e}");
        let e = parse_err("");
        assert!(e.contains("missing HIERARCHY"), "{e}");
    }

    /// End sites some exporters name (`End Site Toe_End {`), and the hierarchy's errors inside a joint,
    /// word for word with their lines.
    #[test]
    fn named_end_sites_are_read_and_joint_errors_name_their_line() {
        let named = SMALL.replace("  End Site\n  {", "  End Site Left_Toe_End {");
        let b = Bvh::parse(&named, "named.bvh").unwrap();
        assert_eq!(b.joints[1].end_sites, [Vector3::new(0.0, -0.4, 0.0)]);
        let spaced = SMALL.replace("  End Site\n  {", "  End Site Left Toe\n  {");
        assert_eq!(Bvh::parse(&spaced, "named.bvh").unwrap().joints[1].end_sites.len(), 1);
        let cases: Vec<(String, &str)> = vec![
            (SMALL.replace("OFFSET 0 -0.4 0", "OFFSET 0 inf 0"), "line 11: expected an OFFSET coordinate, found `inf`"),
            (SMALL.replace("OFFSET 0.1 -0.5 0", "OFFSET 0.1 NaN 0"), "line 7: expected an OFFSET coordinate, found `NaN`"),
            (SMALL.replace("  End Site\n", "  {\n  End Site\n"), "line 9: unbalanced braces: unexpected `{` in joint `Left Leg`"),
            (SMALL.replace("  End Site\n", "  Limits 0 1\n  End Site\n"), "line 9: unexpected `Limits` in joint `Left Leg`"),
            (SMALL.replace("  End Site\n", "  End Point\n"), "line 9: expected `End Site`, found `End Point`"),
        ];
        for (text, message) in cases {
            assert_eq!(parse_err(&text), format!("bad.bvh, {message}"));
        }
    }

    /// Every error of the MOTION section, word for word, with the line it names (SMALL's MOTION is
    /// line 15, `Frames:` 16, `Frame Time:` 17, its frames 18 and 20 with a blank line between).
    #[test]
    fn motion_section_errors_name_their_line_exactly() {
        let (head, _) = SMALL.split_once("Frames:").unwrap();
        let cases: Vec<(String, &str)> = vec![
            (head.to_string(), "line 15: MOTION section has no `Frames:` line"),
            (SMALL.replace("Frames:\t2", "Frame: 2"), "line 16: expected `Frames: <count>` after MOTION, found `Frame: 2`"),
            (SMALL.replace("Frames:\t2", "Frames: two"), "line 16: `Frames:` count `two` is not a non-negative integer"),
            (format!("{head}Frames:\t2\n"), "line 16: MOTION section has no `Frame Time:` line"),
            (SMALL.replace("Frames:\t2", "Frames: 0"), "line 16: `Frames: 0`: the clip has no motion"),
            (SMALL.replace("Frame Time: 0.5", "Frame Tme: 0.5"), "line 17: expected `Frame Time: <seconds>`, found `Frame Tme: 0.5`"),
            (SMALL.replace("Frame Time: 0.5", "Frame Time: 0"), "line 17: `Frame Time:` `0` is not a positive number"),
            (SMALL.replace("Frame Time: 0.5", "Frame Time: -0.5"), "line 17: `Frame Time:` `-0.5` is not a positive number"),
            (SMALL.replace("Frame Time: 0.5", "Frame Time: inf"), "line 17: `Frame Time:` `inf` is not a positive number"),
            (SMALL.replace("Frame Time: 0.5", "Frame Time: NaN"), "line 17: `Frame Time:` `NaN` is not a positive number"),
            (
                SMALL.replace("Frame Time: 0.5", "Frame Time: 20"),
                "line 17: `Frame Time: 20` is 0.0500 frames per second; expected 0.001 to 10 seconds per frame (1000 down to 0.1 frames per second)",
            ),
            (SMALL.replace("Frames:\t2", "Frames: 1"), "line 20: more motion lines than `Frames: 1` declares (line 20 is frame 2); correct the `Frames:` count"),
            (SMALL.replace("1 2 3\n\n", "1 2 3 4\n\n"), "line 18: expected 9 values, found 10"),
            (SMALL.replace("1 2 3e-1", "1 2 3e39"), "line 20: value 9 `3e39` is not finite"),
            (SMALL.replace("1 2 3e-1", "1 x 3"), "line 20: value 8 `x` is not a number"),
            (SMALL.replace("Frames:\t2", "Frames: 3"), "line 20: truncated: `Frames: 3` declared but only 2 motion lines present"),
            (format!("{head}Frames: 2\nFrame Time: 0.5\n"), "line 17: truncated: `Frames: 2` declared but only 0 motion lines present"),
        ];
        for (text, message) in cases {
            assert_eq!(parse_err(&text), format!("bad.bvh, {message}"));
        }
        // Two hours of motion are read, not a frame more.
        let long = |frames: usize| format!("{head}Frames: {frames}\nFrame Time: 10\n{}", "0 1 0 0 0 0 1 2 3\n".repeat(frames));
        assert_eq!(Bvh::parse(&long(720), "long.bvh").unwrap().frame_count, 720);
        assert_eq!(
            parse_err(&long(721)),
            "bad.bvh, line 17: `Frames: 721` at `Frame Time: 10` is 7210 s of motion; clips of at most 7200 s (2 hours) are read: split the clip"
        );
    }
}
