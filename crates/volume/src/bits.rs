//! A growable bit vector with run pushes and bit-range copies, used for start bits and the
//! unary-coded crossing counts of chunk lists.

/// Reads bit `i` of a packed word slice.
#[inline]
pub(crate) fn bit(words: &[u64], i: usize) -> bool {
    (words[i >> 6] >> (i & 63)) & 1 == 1
}

/// Number of consecutive one bits starting at bit `i` (the unary count of one line).
#[inline]
pub(crate) fn ones_run(words: &[u64], mut i: usize) -> usize {
    let mut n = 0;
    loop {
        let w = words[i >> 6] >> (i & 63);
        let run = w.trailing_ones() as usize;
        let avail = 64 - (i & 63);
        if run < avail {
            return n + run;
        }
        n += avail;
        i += avail;
    }
}

/// Mask of the low `n` bits (`n` in `0..=64`).
#[inline]
fn low_bits(n: usize) -> u64 {
    if n >= 64 { u64::MAX } else { (1u64 << n) - 1 }
}

/// Position just after the `k`-th zero bit at or after bit `from`, and the number of ones passed.
/// Used to jump to a line in a unary-coded count stream.
#[inline]
pub(crate) fn skip_zeros(words: &[u64], from: usize, mut k: usize) -> (usize, usize) {
    if k == 0 {
        return (from, 0);
    }
    let mut word = from >> 6;
    let mut w = words[word] >> (from & 63);
    let mut valid = 64 - (from & 63);
    let mut base = from;
    let mut ones = 0;
    loop {
        let zeros = !w & low_bits(valid);
        let z = zeros.count_ones() as usize;
        if z >= k {
            let mut zs = zeros;
            for _ in 1..k {
                zs &= zs - 1;
            }
            let pos = zs.trailing_zeros() as usize;
            ones += (w & low_bits(pos)).count_ones() as usize;
            return (base + pos + 1, ones);
        }
        k -= z;
        ones += (w & low_bits(valid)).count_ones() as usize;
        base += valid;
        word += 1;
        w = words[word];
        valid = 64;
    }
}

/// An append-only bit vector.
#[derive(Clone, Debug, Default)]
pub(crate) struct BitBuf {
    pub(crate) words: Vec<u64>,
    pub(crate) len: usize,
}

impl BitBuf {
    pub(crate) fn clear(&mut self) {
        self.words.clear();
        self.len = 0;
    }

    #[inline]
    pub(crate) fn push(&mut self, b: bool) {
        if self.len & 63 == 0 {
            self.words.push(0);
        }
        if b {
            *self.words.last_mut().expect("a word was pushed") |= 1 << (self.len & 63);
        }
        self.len += 1;
    }

    /// Appends `n` copies of `b`.
    pub(crate) fn push_run(&mut self, b: bool, mut n: usize) {
        while n > 0 {
            if self.len & 63 == 0 {
                self.words.push(0);
            }
            let off = self.len & 63;
            let take = n.min(64 - off);
            if b {
                let mask = if take == 64 { u64::MAX } else { ((1u64 << take) - 1) << off };
                *self.words.last_mut().expect("a word was pushed") |= mask;
            }
            self.len += take;
            n -= take;
        }
    }

    /// Appends bits `[start, start + n)` of `src`.
    pub(crate) fn extend_from(&mut self, src: &[u64], start: usize, n: usize) {
        let mut i = start;
        let end = start + n;
        while i < end {
            let take = (end - i).min(64 - (i & 63)).min(64 - (self.len & 63));
            let w = src[i >> 6] >> (i & 63);
            let mask = if take == 64 { u64::MAX } else { (1u64 << take) - 1 };
            let chunk = w & mask;
            if self.len & 63 == 0 {
                self.words.push(0);
            }
            *self.words.last_mut().expect("a word was pushed") |= chunk << (self.len & 63);
            self.len += take;
            i += take;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn naive(bits: &[bool]) -> BitBuf {
        let mut b = BitBuf::default();
        for &x in bits {
            b.push(x);
        }
        b
    }

    #[test]
    fn runs_copies_and_skips_agree_with_a_bool_vector() {
        let mut seed = 12345u64;
        let mut bits = Vec::new();
        for _ in 0..1000 {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            let run = ((seed >> 33) % 70) as usize;
            let b = (seed >> 20) & 1 == 1;
            bits.extend(std::iter::repeat_n(b, run));
        }
        let a = naive(&bits);
        let mut r = BitBuf::default();
        let mut i = 0;
        while i < bits.len() {
            let n = (bits.len() - i).min(37);
            r.extend_from(&a.words, i, n);
            i += n;
        }
        assert_eq!(r.words, a.words);
        let mut c = BitBuf::default();
        for &x in &bits {
            c.push_run(x, 1);
        }
        assert_eq!(c.words, a.words);
        for from in [0, 3, 64, 65, 130] {
            for k in 0..50 {
                let mut z = 0;
                let mut ones = 0;
                let mut pos = from;
                if k > 0 {
                    for (j, &b) in bits.iter().enumerate().skip(from) {
                        if b {
                            ones += 1;
                        } else {
                            z += 1;
                            if z == k {
                                pos = j + 1;
                                break;
                            }
                        }
                    }
                }
                if k == 0 || z == k {
                    assert_eq!(skip_zeros(&a.words, from, k), (pos, ones), "from {from} k {k}");
                }
            }
            let expect = bits[from..].iter().take_while(|&&b| b).count();
            if from + expect < bits.len() {
                assert_eq!(ones_run(&a.words, from), expect);
            }
        }
    }
}
