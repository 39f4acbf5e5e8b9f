//! Reading the values of a PLY body, ASCII or binary, one at a time and without allocating:
//! every read checks the data left first, so a length or count read from the file can never
//! make the reader run past its end.

use super::header::Scalar;

/// One value as read, before any conversion.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Value {
    /// Any of the six integer types.
    Int(i64),
    /// A `float`.
    Float(f32),
    /// A `double`.
    Double(f64),
}

impl Value {
    /// The value as `f32`, rounded to nearest (integers beyond 2^24 and doubles lose bits).
    pub(super) fn to_f32(self) -> f32 {
        match self {
            Value::Int(i) => i as f32,
            Value::Float(f) => f,
            Value::Double(d) => d as f32,
        }
    }

    /// The integer, for integer types.
    pub(super) fn as_int(self) -> Option<i64> {
        match self {
            Value::Int(i) => Some(i),
            Value::Float(_) | Value::Double(_) => None,
        }
    }
}

/// A cursor over the values of a body. Errors are messages without location; callers add
/// [`ValueSource::location`].
pub(super) trait ValueSource {
    /// Moves to the next element instance (ASCII: its line).
    fn begin_element(&mut self) -> Result<(), String>;
    /// Reads one value of type `ty`.
    fn scalar(&mut self, ty: Scalar) -> Result<Value, String>;
    /// Reads a list length of integer type `len` for items of type `item`; a binary source
    /// also checks that the data left can hold that many items.
    fn list_len(&mut self, len: Scalar, item: Scalar) -> Result<u64, String>;
    /// Skips `n` values of type `ty` (whose presence [`ValueSource::list_len`] checked for
    /// binary sources).
    fn skip(&mut self, ty: Scalar, n: u64) -> Result<(), String>;
    /// Ends the element instance (ASCII: refuses values left on the line).
    fn end_element(&mut self) -> Result<(), String>;
    /// Where the cursor is, for messages: `line N` or `byte N`.
    fn location(&self) -> String;
    /// Bytes after the last element that are not blanks (ASCII) or at all (binary).
    fn trailing_bytes(&self) -> usize;
}

/// Checks a list length read as `value` and converts it.
fn list_length(value: Value) -> Result<u64, String> {
    match value.as_int() {
        Some(n) if n >= 0 => Ok(n as u64),
        Some(n) => Err(format!("negative list length {n}")),
        None => Err("list length is not an integer".to_string()),
    }
}

/// An ASCII body: one line per element instance, values separated by blanks.
pub(super) struct AsciiSource<'a> {
    data: &'a [u8],
    /// Start of the next line in `data`.
    next_line: usize,
    /// Number of the current line in the file (1-based).
    line: usize,
    /// What is left of the current line.
    rest: &'a [u8],
}

impl<'a> AsciiSource<'a> {
    /// A source over `body`, whose first line is line `first_line` of the file.
    pub(super) fn new(body: &'a [u8], first_line: usize) -> Self {
        AsciiSource {
            data: body,
            next_line: 0,
            line: first_line.saturating_sub(1),
            rest: &[],
        }
    }

    fn token(&mut self) -> Option<&'a [u8]> {
        let start = self.rest.iter().position(|b| !b.is_ascii_whitespace())?;
        let rest = &self.rest[start..];
        let len = rest
            .iter()
            .position(u8::is_ascii_whitespace)
            .unwrap_or(rest.len());
        self.rest = &rest[len..];
        Some(&rest[..len])
    }
}

fn parse_token<T: std::str::FromStr>(token: &[u8], ty: Scalar) -> Result<T, String> {
    std::str::from_utf8(token)
        .ok()
        .and_then(|s| s.parse().ok())
        .ok_or_else(|| {
            format!(
                "`{}` is not a valid {}",
                super::header::shorten(&String::from_utf8_lossy(token)),
                ty.name()
            )
        })
}

impl ValueSource for AsciiSource<'_> {
    fn begin_element(&mut self) -> Result<(), String> {
        if self.next_line >= self.data.len() {
            self.line += 1;
            return Err("the file ends here".to_string());
        }
        let tail = &self.data[self.next_line..];
        let len = tail.iter().position(|&b| b == b'\n').unwrap_or(tail.len());
        self.rest = &tail[..len];
        self.next_line += len + 1;
        self.line += 1;
        Ok(())
    }

    fn scalar(&mut self, ty: Scalar) -> Result<Value, String> {
        let token = self
            .token()
            .ok_or_else(|| format!("the line ends where a {} was expected", ty.name()))?;
        Ok(match ty {
            Scalar::Char => Value::Int(parse_token::<i8>(token, ty)?.into()),
            Scalar::UChar => Value::Int(parse_token::<u8>(token, ty)?.into()),
            Scalar::Short => Value::Int(parse_token::<i16>(token, ty)?.into()),
            Scalar::UShort => Value::Int(parse_token::<u16>(token, ty)?.into()),
            Scalar::Int => Value::Int(parse_token::<i32>(token, ty)?.into()),
            Scalar::UInt => Value::Int(parse_token::<u32>(token, ty)?.into()),
            Scalar::Float => Value::Float(parse_token(token, ty)?),
            Scalar::Double => Value::Double(parse_token(token, ty)?),
        })
    }

    fn list_len(&mut self, len: Scalar, _item: Scalar) -> Result<u64, String> {
        // Items are read from the current line only, so a huge length fails at the line's end.
        list_length(self.scalar(len)?)
    }

    fn skip(&mut self, ty: Scalar, n: u64) -> Result<(), String> {
        for _ in 0..n {
            self.scalar(ty)?;
        }
        Ok(())
    }

    fn end_element(&mut self) -> Result<(), String> {
        match self.token() {
            None => Ok(()),
            Some(extra) => Err(format!(
                "unexpected value `{}` after the last property",
                super::header::shorten(&String::from_utf8_lossy(extra))
            )),
        }
    }

    fn location(&self) -> String {
        format!("line {}", self.line)
    }

    fn trailing_bytes(&self) -> usize {
        let tail = self.data.get(self.next_line..).unwrap_or(&[]);
        self.rest
            .iter()
            .chain(tail)
            .filter(|b| !b.is_ascii_whitespace())
            .count()
    }
}

/// A binary body of packed values.
pub(super) struct BinarySource<'a> {
    data: &'a [u8],
    pos: usize,
    /// Offset of `data` in the file, for messages.
    offset: usize,
    big_endian: bool,
}

impl<'a> BinarySource<'a> {
    /// A source over `body`, which starts at byte `offset` of the file.
    pub(super) fn new(body: &'a [u8], offset: usize, big_endian: bool) -> Self {
        BinarySource {
            data: body,
            pos: 0,
            offset,
            big_endian,
        }
    }

    fn remaining(&self) -> usize {
        self.data.len() - self.pos
    }

    /// The next `N` bytes, in big-endian order whatever the file's byte order.
    fn take<const N: usize>(&mut self) -> Result<[u8; N], String> {
        let mut bytes: [u8; N] = self
            .data
            .get(self.pos..self.pos + N)
            .and_then(|s| s.try_into().ok())
            .ok_or_else(|| {
                format!(
                    "the file ends {} bytes into a {N}-byte value",
                    self.remaining()
                )
            })?;
        self.pos += N;
        if !self.big_endian {
            bytes.reverse();
        }
        Ok(bytes)
    }
}

impl ValueSource for BinarySource<'_> {
    fn begin_element(&mut self) -> Result<(), String> {
        Ok(())
    }

    fn scalar(&mut self, ty: Scalar) -> Result<Value, String> {
        Ok(match ty {
            Scalar::Char => Value::Int(i8::from_be_bytes(self.take()?).into()),
            Scalar::UChar => Value::Int(u8::from_be_bytes(self.take()?).into()),
            Scalar::Short => Value::Int(i16::from_be_bytes(self.take()?).into()),
            Scalar::UShort => Value::Int(u16::from_be_bytes(self.take()?).into()),
            Scalar::Int => Value::Int(i32::from_be_bytes(self.take()?).into()),
            Scalar::UInt => Value::Int(u32::from_be_bytes(self.take()?).into()),
            Scalar::Float => Value::Float(f32::from_be_bytes(self.take()?)),
            Scalar::Double => Value::Double(f64::from_be_bytes(self.take()?)),
        })
    }

    fn list_len(&mut self, len: Scalar, item: Scalar) -> Result<u64, String> {
        let n = list_length(self.scalar(len)?)?;
        let needed = u128::from(n) * item.size() as u128;
        if needed > self.remaining() as u128 {
            return Err(format!(
                "a list of {n} {}s needs {needed} bytes but only {} are left",
                item.name(),
                self.remaining()
            ));
        }
        Ok(n)
    }

    fn skip(&mut self, ty: Scalar, n: u64) -> Result<(), String> {
        let bytes = usize::try_from(n)
            .ok()
            .and_then(|n| n.checked_mul(ty.size()))
            .filter(|&b| b <= self.remaining())
            .ok_or_else(|| format!("the file ends within a list of {n} {}s", ty.name()))?;
        self.pos += bytes;
        Ok(())
    }

    fn end_element(&mut self) -> Result<(), String> {
        Ok(())
    }

    fn location(&self) -> String {
        format!("byte {}", self.offset + self.pos)
    }

    fn trailing_bytes(&self) -> usize {
        self.remaining()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn binary_values_in_both_byte_orders() {
        let le = [0x01u8, 0x02, 0xff];
        let mut s = BinarySource::new(&le, 10, false);
        assert_eq!(s.scalar(Scalar::UShort), Ok(Value::Int(0x0201)));
        assert_eq!(s.location(), "byte 12");
        assert_eq!(s.scalar(Scalar::Char), Ok(Value::Int(-1)));
        assert!(s.scalar(Scalar::Char).is_err());
        let mut s = BinarySource::new(&le, 0, true);
        assert_eq!(s.scalar(Scalar::UShort), Ok(Value::Int(0x0102)));
        assert_eq!(s.trailing_bytes(), 1);
    }

    #[test]
    fn binary_list_lengths_must_fit_the_data() {
        let data = [2u8, 0, 0, 0, 0, 0, 0, 0, 0];
        let mut s = BinarySource::new(&data, 0, false);
        assert_eq!(s.list_len(Scalar::UChar, Scalar::Int), Ok(2));
        let mut s = BinarySource::new(&data, 0, false);
        assert!(s.list_len(Scalar::UChar, Scalar::Double).is_err());
        let neg = [0xffu8];
        let mut s = BinarySource::new(&neg, 0, false);
        assert!(s.list_len(Scalar::Char, Scalar::Int).is_err());
    }

    #[test]
    fn ascii_lines_values_and_leftovers() -> Result<(), String> {
        let body = b"1 -2.5\n  7\t\r\n3 4\n\n";
        let mut s = AsciiSource::new(body, 5);
        s.begin_element()?;
        assert_eq!(s.location(), "line 5");
        assert_eq!(s.scalar(Scalar::UChar), Ok(Value::Int(1)));
        assert_eq!(s.scalar(Scalar::Float), Ok(Value::Float(-2.5)));
        assert!(s.scalar(Scalar::Float).is_err());
        s.begin_element()?;
        assert!(s.scalar(Scalar::Char).is_ok());
        assert!(s.end_element().is_ok());
        s.begin_element()?;
        assert!(s.scalar(Scalar::UChar).is_ok());
        assert!(s.end_element().is_err_and(|e| e.contains("`4`")));
        assert_eq!(s.trailing_bytes(), 0);
        let mut bad = AsciiSource::new(b"300 -1 x\n", 1);
        bad.begin_element()?;
        assert!(bad.scalar(Scalar::UChar).is_err());
        assert!(bad.list_len(Scalar::Int, Scalar::Int).is_err());
        assert!(bad.scalar(Scalar::Double).is_err());
        Ok(())
    }
}
