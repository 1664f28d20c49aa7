// MATLAB v5 .mat files, read by our own code. libmatio sized its buffers from sizes found inside
// compressed and nested elements before checking them against anything (the names of a compressed cell
// array's cells, a nested cell's element count, a struct's field names: a 373-byte file asked for
// 3.19 GB), so msid parses only what it needs and checks every size against the bytes present before
// it allocates: each top-level variable's array flags, dimensions and name and, for a real numeric 2-D
// matrix, its real part. A cell, struct, sparse, char, object or function handle is described by its
// flags and skipped whole: nothing inside it is read, so nothing inside it sizes memory.
//
// Layout (MathWorks, "MAT-File Format", the Level 5 chapter): a 128-byte header (text, the subsystem
// data's offset, version 0x0100, "IM", or "MI" when written big-endian), then elements. An element is an
// 8-byte tag (type, byte count) and its data padded to 8 bytes, or a small element (a byte count of at
// most 4 in the upper half of the type word, the data in the tag's last 4 bytes). A variable is an
// miMATRIX element, or an miCOMPRESSED element holding one miMATRIX, zlib-compressed (not padded). A
// matrix holds sub-elements: array flags (miUINT32: class, complex/global/logical bits; nzmax),
// dimensions (miINT32), name (miINT8), the real part (any numeric type: MATLAB stores a class in a
// narrower type when its values fit), the imaginary part.
//
// Memory: an uncompressed variable is viewed in the mapped file; a compressed one's real part is
// inflated into a buffer of its declared size, which must fit in the matrix's declared size, itself at
// most 1032 times the compressed bytes (DEFLATE_MAX_RATIO); its dimensions times the stored element
// size must fit in the real part. So a variable costs at most 1032 x its compressed bytes, and its
// samples as doubles at most 8 x that.
#include "binary_detail.hpp"

#include <algorithm>
#include <climits>
#include <deque>
#include <zlib.h>

namespace msidrec {

namespace {

enum : uint32_t { MI_INT8 = 1, MI_INT32 = 5, MI_UINT32 = 6, MI_MATRIX = 14, MI_COMPRESSED = 15 };
constexpr uint32_t MAX_RANK = 32;
constexpr uint32_t F_COMPLEX = 0x800, F_LOGICAL = 0x200;

// The element type of a stored numeric part: kind ('f', 'i', 'u') and size in bytes; size 0: not numeric.
struct Stored { char kind; size_t size; };
Stored stored_type(uint32_t t)
{
    switch (t) {
    case 1: return {'i', 1};    // miINT8
    case 2: return {'u', 1};    // miUINT8
    case 3: return {'i', 2};    // miINT16
    case 4: return {'u', 2};    // miUINT16
    case 5: return {'i', 4};    // miINT32
    case 6: return {'u', 4};    // miUINT32
    case 7: return {'f', 4};    // miSINGLE
    case 9: return {'f', 8};    // miDOUBLE
    case 12: return {'i', 8};   // miINT64
    case 13: return {'u', 8};   // miUINT64
    default: return {'f', 0};
    }
}

// The bytes of one matrix: a span of the mapped file (an miMATRIX element, read in place) or a zlib
// stream (miCOMPRESSED), inflated as it is read and never further than asked.
class MatrixBytes {
  public:
    MatrixBytes() = default;
    MatrixBytes(const MatrixBytes &) = delete;
    MatrixBytes &operator=(const MatrixBytes &) = delete;
    ~MatrixBytes() { end_stream(); }

    void span(const unsigned char *p, size_t n)
    {
        end_stream();
        p_ = p;
        n_ = n;
        pos_ = 0;
    }
    bool stream(const unsigned char *p, uint32_t n)
    {
        end_stream();
        zs_ = z_stream{};
        if (inflateInit(&zs_) != Z_OK) return false;
        zs_.next_in = const_cast<unsigned char *>(p);
        zs_.avail_in = n;
        z_ = true;
        pos_ = 0;
        return true;
    }
    bool in_place() const { return !z_; }
    // In place only: the next byte, then `n` bytes skipped.
    const unsigned char *here() const { return p_ + pos_; }
    // The next n bytes into dst (dst null: skipped); false when the bytes end first.
    bool read(void *dst, size_t n)
    {
        if (!z_) {
            if (n > n_ - pos_) return false;
            if (dst) std::memcpy(dst, p_ + pos_, n);
            pos_ += n;
            return true;
        }
        unsigned char scratch[256];
        auto *out = (unsigned char *)dst;
        while (n) {
            const size_t step = out ? std::min<size_t>(n, UINT_MAX) : std::min(n, sizeof scratch);
            zs_.next_out = out ? out : scratch;
            zs_.avail_out = (uInt)step;
            const int rc = inflate(&zs_, Z_NO_FLUSH);
            const size_t got = step - zs_.avail_out;
            if (got == 0 && rc != Z_OK) return false;   // stream end, corrupt data or no more input
            if (got == 0 && zs_.avail_in == 0) return false;
            n -= got;
            pos_ += got;
            if (out) out += got;
        }
        return true;
    }

  private:
    void end_stream()
    {
        if (z_) inflateEnd(&zs_);
        z_ = false;
    }
    const unsigned char *p_ = nullptr;
    size_t n_ = 0, pos_ = 0;
    bool z_ = false;
    z_stream zs_{};
};

class MatV5 : public MatReader {
  public:
    MatV5(std::string path, std::unique_ptr<FileBytes> f) : path_(std::move(path)), f_(std::move(f))
    {
        b_ = (const unsigned char *)f_->data();
        N_ = f_->size();
        swap_ = b_[126] == 'M';
        uint64_t sub = 0;
        for (int i = 0; i < 8; ++i) sub |= (uint64_t)b_[116 + i] << (swap_ ? 8 * (7 - i) : 8 * i);
        // an offset of 0 or of blanks: no subsystem data (MATLAB's objects and function handles keep
        // their own data there, in an unnamed uint8 matrix that is no variable)
        // (an offset beyond the file names no element: on a 32-bit build it must not wrap onto one)
        subsys_ = sub == 0 || sub == 0x2020202020202020ull || sub >= N_ ? SIZE_MAX : (size_t)sub;
    }

    bool next(MatVarInfo &v) override;
    Array read() override;

  private:
    uint32_t u32(const unsigned char *q) const
    {
        return swap_ ? (uint32_t)q[0] << 24 | (uint32_t)q[1] << 16 | (uint32_t)q[2] << 8 | q[3] : le32(q);
    }
    Error bad(const char *what) const
    {
        return Error(fmt("'%s' is not a MATLAB .mat file or is corrupt: variable %zu %s", path_.c_str(), k_, what));
    }
    // A sub-element's tag: type, byte count and, for a small element, its data; false when the
    // matrix's bytes end first. A normal sub-element must fit in what is left of the matrix.
    struct Tag { uint32_t type = 0, bytes = 0; bool small = false; unsigned char data[4] = {}; };
    bool tag(Tag &t)
    {
        unsigned char h[8];
        if (used_ + 8 > limit_ || !m_.read(h, 8)) return false;
        used_ += 8;
        const uint32_t w = u32(h);
        t.small = (w >> 16) != 0;
        t.type = t.small ? w & 0xFFFFu : w;
        t.bytes = t.small ? w >> 16 : u32(h + 4);
        std::memcpy(t.data, h + 4, 4);
        if (t.small && t.bytes > 4) return true;   // malformed: the caller names the part
        if (!t.small && t.bytes > limit_ - used_) throw bad("holds a part longer than the variable");
        return true;
    }
    // The data of a normal sub-element (padded to 8 bytes) into dst (null: skipped).
    void body(const Tag &t, void *dst)
    {
        const size_t pad = ((size_t)t.bytes + 7) / 8 * 8;
        if (!m_.read(dst, t.bytes) || !m_.read(nullptr, std::min<size_t>(pad, limit_ - used_) - t.bytes))
            throw bad("is truncated");
        used_ += std::min<size_t>(pad, limit_ - used_);
    }
    void parse_matrix(MatVarInfo &v);
    // A matrix's array flags, dimensions and name (the start of every matrix, nested ones too).
    struct Head { uint32_t cls = 0; bool complex = false, logical = false; std::vector<uint64_t> dims; uint64_t elems = 1; std::string name; };
    Head parse_head();
    // read_value(): a numeric part (tag t already read) as doubles; a char matrix's data; a cell's elements.
    std::vector<double> numeric_part(const Tag &t, uint64_t elems);
    std::string char_data(const Head &h);
    MatValue read_value() override;

    std::string path_;
    std::unique_ptr<FileBytes> f_;
    const unsigned char *b_ = nullptr;
    size_t N_ = 0, p_ = 128, k_ = 0, subsys_ = SIZE_MAX;
    bool swap_ = false;
    MatrixBytes m_;               // the current matrix's bytes
    uint64_t limit_ = 0, used_ = 0;   // its declared size; bytes of it consumed
    // the real part of the variable next() described
    Tag data_;
    uint64_t elems_ = 0, d0_ = 0, d1_ = 0;
    const unsigned char *data_at_ = nullptr;   // in place
    std::string name_;
    // inflated real parts, alive as long as the reader; a deque, whose elements never move: an Array
    // points into them, and a short string keeps its bytes inside itself (a vector's reallocation
    // moved a 4-byte part and freed the bytes an earlier Array read: found by fuzz_files)
    std::deque<std::string> bufs_;
    Head head_;                       // the variable next() described
    bool data_tag_read_ = false;      // its real part's tag read (a real numeric 2-D matrix)
};

bool MatV5::next(MatVarInfo &v)
{
    while (p_ + 8 <= N_) {
        ++k_;
        const size_t at = p_;
        const uint32_t type = u32(b_ + at), nbytes = u32(b_ + at + 4);
        if (type >> 16) { p_ += 8; continue; }   // a small element: its data is in the tag
        if (nbytes > N_ - at - 8) throw bad("claims more bytes than the file holds");
        p_ = at + 8 + nbytes;
        if (type != MI_COMPRESSED) p_ = std::min(N_, (p_ + 7) / 8 * 8);   // uncompressed elements are padded
        if (at == subsys_) continue;
        if (type == MI_MATRIX) {
            m_.span(b_ + at + 8, nbytes);
            limit_ = nbytes;
        } else if (type == MI_COMPRESSED) {
            unsigned char h[8];
            if (!m_.stream(b_ + at + 8, nbytes)) throw Error("zlib: inflateInit failed");
            if (!m_.read(h, 8) || u32(h) != MI_MATRIX) continue;   // not a matrix: no variable
            limit_ = u32(h + 4);
            if (limit_ > (uint64_t)nbytes * DEFLATE_MAX_RATIO)
                throw bad(fmt("claims %llu bytes, more than its %u compressed bytes can hold", (unsigned long long)limit_,
                              nbytes).c_str());
        } else {
            continue;   // not a variable
        }
        used_ = 0;
        parse_matrix(v);
        return true;
    }
    return false;
}

MatV5::Head MatV5::parse_head()
{
    Head h;
    Tag t;
    unsigned char fl[8];
    if (!tag(t) || t.small || t.type != MI_UINT32 || t.bytes != 8) throw bad("has malformed array flags");
    body(t, fl);
    const uint32_t flags = u32(fl);
    h.cls = flags & 0xFFu;
    h.complex = flags & F_COMPLEX;
    h.logical = flags & F_LOGICAL;
    if (!tag(t)) throw bad("is truncated");
    if (t.small && t.bytes > 4) throw bad("has a malformed dimensions element");
    if (t.type != MI_INT32 || t.bytes % 4 != 0 || t.bytes / 4 > MAX_RANK)
        throw bad(fmt("claims %u bytes of dimensions (at most %u dimensions are read)", t.bytes, MAX_RANK).c_str());
    unsigned char dims[4 * MAX_RANK];
    if (t.small) std::memcpy(dims, t.data, t.bytes);
    else body(t, dims);
    for (uint32_t i = 0; i < t.bytes / 4; ++i) {
        const uint64_t d = u32(dims + 4 * i);
        h.dims.push_back(d);
        h.elems = d && h.elems > UINT64_MAX / d ? UINT64_MAX : h.elems * d;
    }
    if (!tag(t)) throw bad("is truncated");
    if (t.small && t.bytes > 4) throw bad("has a malformed name element");
    if (t.small) {
        h.name.assign((const char *)t.data, t.bytes);
    } else {
        if (t.bytes > limit_ - used_) throw bad("claims a name longer than its bytes");
        h.name.assign(t.bytes, '\0');   // at most the matrix's bytes, checked above
        body(t, &h.name[0]);
    }
    if (t.type != MI_INT8) h.name.clear();   // as libmatio: only an miINT8 name is a name
    h.name.resize(std::strlen(h.name.c_str()));
    return h;
}

void MatV5::parse_matrix(MatVarInfo &v)
{
    v = MatVarInfo{};
    head_ = parse_head();
    data_tag_read_ = false;
    const uint64_t elems = head_.elems;
    v.rank = (int)head_.dims.size();
    v.d0 = v.rank > 0 ? head_.dims[0] : 0;
    v.d1 = v.rank > 1 ? head_.dims[1] : 0;
    v.name = head_.name;
    v.numeric = head_.cls >= 6 && head_.cls <= 15;   // double, single, int8 .. uint64
    v.complex = head_.complex;
    v.logical = head_.logical;
    name_ = v.name;
    data_at_ = nullptr;
    if (!v.numeric || v.rank != 2 || v.complex || v.logical) return;
    // the real part: its dimensions times the stored element size must fit in it (an empty matrix may
    // end before it)
    if (elems == 0 && used_ + 8 > limit_) data_ = Tag{9, 0, false, {}};
    else if (!tag(data_) || (data_.small && data_.bytes > 4)) throw bad("has a malformed data element");
    data_tag_read_ = true;
    const Stored s = stored_type(data_.type);
    if (m_.in_place()) data_at_ = m_.here();
    elems_ = elems;
    d0_ = v.d0;
    d1_ = v.d1;
    const uint64_t es = s.size ? s.size : 1;
    v.claimed = elems > UINT64_MAX / es ? UINT64_MAX : elems * es;
    v.holds = data_.bytes;
}

Array MatV5::read()
{
    const Stored s = stored_type(data_.type);
    if (!s.size) throw Error("'" + path_ + "' variable '" + name_ + "': unsupported element type");
    Array a;
    a.name = name_;
    a.kind = s.kind;
    a.esize = s.size;
    a.swap = swap_ && s.size > 1;
    const size_t bytes = (size_t)(elems_ * s.size);   // <= data_.bytes (next()'s claimed <= holds)
    if (data_.small) {
        bufs_.emplace_back((const char *)data_.data, 4);
        a.data = (const unsigned char *)bufs_.back().data();
    } else if (m_.in_place()) {
        a.data = data_at_;
    } else {
        bufs_.emplace_back(bytes, '\0');   // at most 1032 x the compressed bytes (see next())
        if (!m_.read(&bufs_.back()[0], bytes))
            throw Error("'" + path_ + "' variable '" + name_ + "': cannot read its data (truncated or corrupt file)");
        a.data = (const unsigned char *)bufs_.back().data();
    }
    // MATLAB is column-major: (r, c) at r + c*R
    const size_t R = (size_t)d0_, Cc = (size_t)d1_;
    if (Cc > R) { a.n = Cc; a.C = R; a.si = R; a.sc = 1; }
    else { a.n = R; a.C = Cc; a.si = 1; a.sc = R; }
    return a;
}

std::vector<double> MatV5::numeric_part(const Tag &t, uint64_t elems)
{
    const Stored st = stored_type(t.type);
    if (!st.size) throw Error("'" + path_ + "' variable '" + name_ + "': unsupported element type");
    // the dimensions times the stored size must fit in the part, itself within the matrix's bytes
    if (elems > t.bytes / st.size)
        throw bad(fmt("claims %llu values, more than its %u bytes of data hold", (unsigned long long)elems, t.bytes).c_str());
    std::string raw;
    if (t.small) raw.assign((const char *)t.data, 4);
    else {
        raw.assign(t.bytes, '\0');
        body(t, &raw[0]);
    }
    Array a;
    a.data = (const unsigned char *)raw.data();
    a.kind = st.kind;
    a.esize = st.size;
    a.swap = swap_ && st.size > 1;
    a.si = 1;
    std::vector<double> v((size_t)elems);
    for (size_t i = 0; i < v.size(); ++i) v[i] = a.at(i, 0);
    return v;
}

// A char matrix's data (after its head) as text: one row (1 x N), UTF-16 or UTF-8/bytes stored.
std::string MatV5::char_data(const Head &h)
{
    if (h.cls != 4) throw bad("holds a cell that is not text");
    if (h.dims.size() != 2 || (h.dims[0] > 1 && h.dims[1] > 0))
        throw bad("holds text that is not one row");
    Tag t;
    if (h.elems == 0) return "";
    if (!tag(t) || (t.small && t.bytes > 4)) throw bad("has a malformed text element");
    const bool wide = t.type == 3 || t.type == 4 || t.type == 17;   // miINT16, miUINT16, miUTF16
    const size_t es = wide ? 2 : 1;
    if (h.elems > t.bytes / es) throw bad("claims more characters than its text element holds");
    std::string raw;
    if (t.small) raw.assign((const char *)t.data, 4);
    else {
        raw.assign(t.bytes, '\0');
        body(t, &raw[0]);
    }
    std::string out;
    for (size_t i = 0; i < (size_t)h.elems; ++i) {
        const unsigned c = wide ? (swap_ ? (unsigned)(unsigned char)raw[2 * i] << 8 | (unsigned char)raw[2 * i + 1]
                                         : (unsigned char)raw[2 * i] | (unsigned)(unsigned char)raw[2 * i + 1] << 8)
                                : (unsigned char)raw[i];
        out += c < 128 || !wide ? (char)c : '?';
    }
    return out;
}

MatValue MatV5::read_value()
{
    MatValue v;
    v.name = head_.name;
    v.dims = head_.dims;
    const uint64_t elems = head_.elems;
    if (head_.cls >= 6 && head_.cls <= 15) {
        v.kind = MatValue::Numeric;
        if (elems == 0) return v;
        if (!data_tag_read_ && (!tag(data_) || (data_.small && data_.bytes > 4)))
            throw bad("has a malformed data element");
        v.re = numeric_part(data_, elems);
        if (head_.complex) {
            Tag t;
            if (!tag(t) || (t.small && t.bytes > 4)) throw bad("has a malformed imaginary part");
            v.im = numeric_part(t, elems);
        }
    } else if (head_.cls == 4) {
        v.kind = MatValue::Char;
        v.text = char_data(head_);
    } else if (head_.cls == 1) {
        v.kind = MatValue::Cells;
        // every cell is a matrix of at least its tag and three parts: 8 x 4 bytes
        if (elems > (limit_ - used_) / 32) throw bad("claims more cells than its bytes hold");
        for (uint64_t k = 0; k < elems; ++k) {
            Tag t;
            if (!tag(t) || t.small || t.type != MI_MATRIX) throw bad("has a malformed cell");
            // the cell's own bytes (within the variable's: tag() checked), read to their end: an empty
            // char keeps a data element of 0 bytes that char_data() does not read (libmatio writes one,
            // so `msid export --mat` of an FRF without units could not be imported back)
            const uint64_t end = used_ + t.bytes;
            const Head h = parse_head();
            v.cells.push_back(char_data(h));
            if (used_ < end) {
                if (!m_.read(nullptr, (size_t)(end - used_))) throw bad("is truncated");
                used_ = end;
            }
        }
    }
    return v;
}

}  // namespace

std::vector<MatValue> read_mat_values(const std::string &path, const std::vector<std::string> &names)
{
    std::unique_ptr<MatReader> mr = open_mat_v5(path);
    if (!mr) {
        const FileBytes f(path);
        if (mat_header_version((const unsigned char *)f.data(), f.size()) == 0x0200)
            return read_mat_values_v73(path, f.size(), names);
        throw Error("'" + path + "' is not a MATLAB v5 or v7.3 .mat file (v4 is not read here; save with -v7, -v6 or -v7.3)");
    }
    std::vector<MatValue> out;
    MatVarInfo info;
    while (mr->next(info))
        if (std::find(names.begin(), names.end(), info.name) != names.end()) out.push_back(mr->read_value());
    return out;
}

unsigned mat_header_version(const unsigned char *b, size_t N)
{
    if (N < 128 || !((b[126] == 'I' && b[127] == 'M') || (b[126] == 'M' && b[127] == 'I'))) return 0;
    const unsigned v = b[126] == 'M' ? (unsigned)b[124] << 8 | b[125] : (unsigned)b[125] << 8 | b[124];
    return v == 0x0100 || v == 0x0200 ? v : 0;
}

std::unique_ptr<MatReader> open_mat_v5(const std::string &path)
{
    auto f = std::make_unique<FileBytes>(path);
    if (mat_header_version((const unsigned char *)f->data(), f->size()) != 0x0100) return nullptr;
    return std::make_unique<MatV5>(path, std::move(f));
}

}  // namespace msidrec
