//! A whitespace tokenizer over text with line and column tracking, shared by the text formats.
//! Accepts LF and CRLF (a `\r` is whitespace).

use crate::error::{Error, ErrorKind, Location, shorten};

/// One whitespace-separated token and where it starts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Token<'a> {
    pub text: &'a str,
    pub line: usize,
    pub col: usize,
}

impl Token<'_> {
    pub fn location(&self) -> Location {
        Location::at(self.line, self.col)
    }

    pub fn error(&self, kind: ErrorKind) -> Error {
        Error::parse(self.location(), kind)
    }

    pub fn expected(&self, expected: &'static str) -> Error {
        self.error(ErrorKind::Expected { expected, found: shorten(self.text) })
    }

    /// Parses the token as a number (NaN and infinities included; callers check finiteness).
    pub fn f64(&self) -> Result<f64, Error> {
        parse_f64(self.text).ok_or_else(|| self.error(ErrorKind::BadNumber(shorten(self.text))))
    }

    /// Parses a finite number; `what` names it in the error.
    pub fn finite(&self, what: &'static str) -> Result<f64, Error> {
        let v = self.f64()?;
        if v.is_finite() { Ok(v) } else { Err(self.error(ErrorKind::NonFiniteHeader(what))) }
    }

    /// Parses a non-negative integer.
    pub fn usize(&self) -> Result<usize, Error> {
        self.text.parse::<usize>().map_err(|_| self.error(ErrorKind::BadNumber(shorten(self.text))))
    }
}

/// Parses a decimal number as written in mocap files (`1.5`, `.0083`, `-2e-3`, `nan`, `inf`).
pub(crate) fn parse_f64(s: &str) -> Option<f64> {
    // Rust's parser takes a leading '+', exponents, "inf", "infinity" and "nan"; reject the
    // hexadecimal or empty forms it never accepts anyway. Guard very long tokens: they are
    // numbers no writer produces, and parsing them is wasted time.
    if s.is_empty() || s.len() > 64 {
        return None;
    }
    s.parse::<f64>().ok()
}

/// Checks the input is UTF-8, naming the line of the first bad byte.
pub(crate) fn utf8(bytes: &[u8]) -> Result<&str, Error> {
    std::str::from_utf8(bytes).map_err(|e| {
        let good = bytes.get(..e.valid_up_to()).unwrap_or_default();
        let line = 1 + good.iter().filter(|&&b| b == b'\n').count();
        let col = 1 + good.iter().rev().take_while(|&&b| b != b'\n').count();
        Error::parse(Location::at(line, col), ErrorKind::InvalidUtf8)
    })
}

/// A cursor over text yielding tokens and whole lines.
pub(crate) struct Scanner<'a> {
    src: &'a str,
    pos: usize,
    line: usize,
    line_start: usize,
}

impl<'a> Scanner<'a> {
    pub fn new(src: &'a str) -> Self {
        Scanner { src, pos: 0, line: 1, line_start: 0 }
    }

    /// Line of the cursor (1-based).
    pub fn line(&self) -> usize {
        self.line
    }

    /// Bytes not yet consumed.
    pub fn remaining(&self) -> usize {
        self.src.len().saturating_sub(self.pos)
    }

    fn skip_ws(&mut self) {
        let bytes = self.src.as_bytes();
        while let Some(&b) = bytes.get(self.pos) {
            if b == b'\n' {
                self.pos += 1;
                self.line += 1;
                self.line_start = self.pos;
            } else if b.is_ascii_whitespace() {
                self.pos += 1;
            } else {
                break;
            }
        }
    }

    /// The next token, or `None` at the end of input.
    pub fn next_token(&mut self) -> Option<Token<'a>> {
        self.skip_ws();
        let bytes = self.src.as_bytes();
        let start = self.pos;
        while let Some(&b) = bytes.get(self.pos) {
            if b.is_ascii_whitespace() {
                break;
            }
            self.pos += 1;
        }
        if self.pos == start {
            return None;
        }
        // Token boundaries are ASCII whitespace, so they are char boundaries.
        let text = self.src.get(start..self.pos)?;
        Some(Token { text, line: self.line, col: start - self.line_start + 1 })
    }

    /// The next token, or an end-of-input error naming what was expected.
    pub fn expect_token(&mut self, expected: &'static str) -> Result<Token<'a>, Error> {
        self.next_token().ok_or_else(|| Error::parse(self.eof_location(), ErrorKind::UnexpectedEof(expected)))
    }

    /// The next token, which must equal `word` (ASCII case-insensitive).
    pub fn expect_word(&mut self, word: &'static str) -> Result<Token<'a>, Error> {
        let t = self.expect_token(word)?;
        if t.text.eq_ignore_ascii_case(word) { Ok(t) } else { Err(t.expected(word)) }
    }

    /// The rest of the current line after the cursor, trimmed, consuming the line break.
    /// Returns the text and the column where it starts.
    pub fn rest_of_line(&mut self) -> (&'a str, usize) {
        let bytes = self.src.as_bytes();
        let start = self.pos;
        while let Some(&b) = bytes.get(self.pos) {
            if b == b'\n' {
                break;
            }
            self.pos += 1;
        }
        let raw = self.src.get(start..self.pos).unwrap_or_default();
        let col = start - self.line_start + 1;
        if self.pos < self.src.len() {
            // Consume the '\n'.
            self.pos += 1;
            self.line += 1;
            self.line_start = self.pos;
        }
        let lead = raw.len() - raw.trim_start().len();
        (raw.trim(), col + lead)
    }

    /// The next whole line (without its line break or `\r`) and its number, or `None` at
    /// the end.
    pub fn next_line(&mut self) -> Option<(usize, &'a str)> {
        if self.pos >= self.src.len() {
            return None;
        }
        let line = self.line;
        let bytes = self.src.as_bytes();
        let start = self.pos;
        while let Some(&b) = bytes.get(self.pos) {
            if b == b'\n' {
                break;
            }
            self.pos += 1;
        }
        let raw = self.src.get(start..self.pos).unwrap_or_default();
        if self.pos < self.src.len() {
            self.pos += 1;
            self.line += 1;
            self.line_start = self.pos;
        }
        Some((line, raw.strip_suffix('\r').unwrap_or(raw)))
    }

    /// Location just past the last byte, for end-of-input errors.
    pub fn eof_location(&self) -> Location {
        Location::at(self.line, self.pos.saturating_sub(self.line_start) + 1)
    }
}

/// Splits one line into tokens carrying `line` and their columns.
pub(crate) fn line_tokens(line: usize, text: &str) -> impl Iterator<Item = Token<'_>> {
    let base = text.as_ptr() as usize;
    text.split_ascii_whitespace().map(move |t| Token { text: t, line, col: t.as_ptr() as usize - base + 1 })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tokens_track_lines_and_columns_across_crlf() {
        let mut s = Scanner::new("A b\r\n\tcc\r\n\r\nd");
        let t: Vec<_> = std::iter::from_fn(|| s.next_token()).map(|t| (t.text, t.line, t.col)).collect();
        assert_eq!(t, [("A", 1, 1), ("b", 1, 3), ("cc", 2, 2), ("d", 4, 1)]);
    }

    #[test]
    fn rest_of_line_trims_and_advances() {
        let mut s = Scanner::new("JOINT  left arm \r\n{");
        assert_eq!(s.next_token().map(|t| t.text), Some("JOINT"));
        assert_eq!(s.rest_of_line(), ("left arm", 8));
        assert_eq!(s.next_token().map(|t| (t.text, t.line)), Some(("{", 2)));
    }

    #[test]
    fn lines_strip_cr() {
        let mut s = Scanner::new("a b\r\nc\n");
        assert_eq!(s.next_line(), Some((1, "a b")));
        assert_eq!(s.next_line(), Some((2, "c")));
        assert_eq!(s.next_line(), None);
    }

    #[test]
    fn utf8_error_names_line() {
        let e = utf8(b"ok\nok\n\xff").unwrap_err();
        assert_eq!(e.location().map(|l| l.line), Some(3));
    }

    #[test]
    fn numbers() {
        assert_eq!(parse_f64(".0083333"), Some(0.0083333));
        assert_eq!(parse_f64("-1e-14"), Some(-1e-14));
        assert!(parse_f64("nan").is_some_and(f64::is_nan));
        assert_eq!(parse_f64("1,5"), None);
        assert_eq!(parse_f64(""), None);
    }
}
