//! Names and values quoted in error messages: on one line and of bounded length.

/// Longest name or value quoted in an error message; longer ones are cut with `…`.
pub(crate) const QUOTE_MAX: usize = 60;

/// `s` for an error message: control characters escaped (a message stays one line) and cut
/// after [`QUOTE_MAX`] characters.
pub(crate) fn quote(s: &str) -> String {
    let mut out = escape(&s.chars().take(QUOTE_MAX).collect::<String>());
    if s.chars().nth(QUOTE_MAX).is_some() {
        out.push('…');
    }
    out
}

/// `s` with control characters escaped, so that an error message stays one line.
pub(crate) fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        if c.is_control() {
            out.extend(c.escape_default());
        } else {
            out.push(c);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quotes_are_one_line_and_bounded() {
        assert_eq!(quote("a\u{1b}b\rc"), "a\\u{1b}b\\rc");
        assert_eq!(
            quote(&"x".repeat(100)),
            format!("{}…", "x".repeat(QUOTE_MAX))
        );
        assert_eq!(quote(&"x".repeat(QUOTE_MAX)), "x".repeat(QUOTE_MAX));
    }
}
