//! Untrusted text (titles and names from BCF files, entry names, model
//! names, error messages quoting them) made safe to print on a terminal.

use std::borrow::Cow;
use std::fmt::Write as _;

/// `s` with every character a terminal would act on written as an escape
/// (`\n`, `\u{1b}`, `\0`...): C0 controls (newline and tab too), DEL, C1
/// controls, and the bidirectional overrides and isolates that reorder what
/// is shown. So untrusted text can neither send escape codes to the terminal
/// nor start a line of its own (a title holding "\ndmu: error: ..." forged an
/// error line), and one record stays one line. At most `max_chars`
/// characters of `s` are kept, then `…`.
pub fn printable(s: &str, max_chars: usize) -> Cow<'_, str> {
    let needs_escape = |c: char| {
        c.is_control()
            || matches!(c, '\u{200e}' | '\u{200f}' | '\u{202a}'..='\u{202e}' | '\u{2066}'..='\u{2069}')
    };
    let long = s.chars().nth(max_chars).is_some();
    if !long && !s.chars().any(needs_escape) {
        return Cow::Borrowed(s);
    }
    let mut out = String::with_capacity(s.len().min(max_chars * 2));
    for c in s.chars().take(max_chars) {
        if needs_escape(c) {
            // `escape_debug` writes `\n`, `\t`, `\0`, `\u{1b}`.
            let _ = write!(out, "{}", c.escape_debug());
        } else {
            out.push(c);
        }
    }
    if long {
        out.push('…');
    }
    Cow::Owned(out)
}

/// How many characters of a message line are printed (an error naming a
/// 16 MiB XML text does not print it).
pub const MESSAGE_CHARS: usize = 2_000;

/// The one line a program prints for the error that stops it:
/// `PROGRAM: error: ` and the error with its causes, escaped ([`printable`]),
/// one line whatever the file or flag it quotes held.
pub fn error_line(program: &str, e: &anyhow::Error) -> String {
    format!(
        "{program}: error: {}",
        printable(&format!("{e:#}"), MESSAGE_CHARS)
    )
}

/// A product a converter left out, as reports print it: name (class):
/// reason, escaped ([`printable`]).
pub fn failed_product(f: &dmu_scene::FailedProduct) -> String {
    format!(
        "{} ({}): {}",
        printable(&f.name, 200),
        printable(&f.class, 80),
        printable(&f.reason, 400)
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Issue 48: `dmu bcf show` printed titles raw (escape codes, a newline
    /// forging a `dmu: error:` line) and a NUL byte of an entry name reached
    /// the terminal.
    #[test]
    fn issue_48_control_characters_are_escaped() {
        assert_eq!(printable("pump 3 × pipe", 100), "pump 3 × pipe");
        assert!(matches!(printable("plain", 100), Cow::Borrowed(_)));
        let forged = printable("title\ndmu: error: forged\u{1b}[2J\0\u{202e}x\u{9b}", 100);
        assert_eq!(
            forged,
            "title\\ndmu: error: forged\\u{1b}[2J\\0\\u{202e}x\\u{9b}"
        );
        assert!(!forged.chars().any(char::is_control));
        assert_eq!(printable("abcdef", 3), "abc…");
        assert_eq!(printable("abc", 3), "abc");
    }
}
