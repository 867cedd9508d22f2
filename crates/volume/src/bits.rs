//! A growable bit vector with zero-run pushes and bit-range copies, used for the nonempty-line bits
//! of chunk lists.

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

    /// Appends `n` zero bits.
    #[inline]
    pub(crate) fn push_zeros(&mut self, n: usize) {
        self.len += n;
        let need = self.len.div_ceil(64);
        if self.words.len() < need {
            self.words.resize(need, 0);
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
    fn runs_and_copies_agree_with_a_bool_vector() {
        let mut seed = 12345u64;
        let (mut bits, mut runs) = (Vec::new(), Vec::new());
        for _ in 0..1000 {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            let run = ((seed >> 33) % 70) as usize;
            let b = (seed >> 20) & 1 == 1;
            bits.extend(std::iter::repeat_n(b, run));
            runs.push((b, run));
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
        for &(b, run) in &runs {
            if b {
                (0..run).for_each(|_| c.push(true));
            } else {
                c.push_zeros(run);
            }
        }
        assert_eq!((c.len, &c.words), (a.len, &a.words));
    }
}
