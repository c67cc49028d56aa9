//! Fitting texts into the fixed capacity of a VISIBLE_STRING entry.

/// `text` cut to at most `max` bytes, on a character boundary.
pub(crate) fn fit(text: &str, max: usize) -> &str {
    if text.len() <= max {
        return text;
    }
    let mut end = max;
    while !text.is_char_boundary(end) {
        end -= 1;
    }
    &text[..end]
}

#[cfg(test)]
mod tests {
    use super::fit;

    #[test]
    fn cuts_on_character_boundaries() {
        assert_eq!(fit("abc", 8), "abc");
        assert_eq!(fit("abcdef", 4), "abcd");
        assert_eq!(fit("aé", 2), "a");
    }
}
