// The CSV reader (',', ';' or tab; named columns, quoted cells, '#' lines before the header).
//
// Speed and memory: the file is streamed in blocks of about 4 MiB (mapped
// window by window; a pipe by read(2)), never held whole: peak memory is the
// samples plus a constant. Cells are parsed in place (no per-cell or per-line strings); a block over 1 MiB is
// split at a line boundary and its halves parsed by two threads, joined in
// file order (values, errors and so every result are independent of the
// block size and the split). read_experiments() reads two files at once
// instead (one thread each, no split), reporting the first bad file in order.
#include "records_detail.hpp"
#include "msid_csv_cells.hpp"
#include "msid_decimal.hpp"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <exception>
#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <system_error>
#include <thread>
#include <unistd.h>

namespace msidrec {

// -------------------------------------------------------------------- CSV ---

namespace {

// Numbers: msid_decimal.hpp (correctly rounded, bit-identical to std::from_chars).

struct CsvLayout {
    const std::string *path;
    const char *text;            // block start (line numbers count from here)
    size_t line0 = 0;            // lines of the file before `text`
    char delim;
    char point = '.';            // the cell parser's decimal separator (',': a decimal-comma file)
    std::vector<int> dest;       // per file column: destination column or -1
    std::vector<std::string> names;
    size_t C;
    bool cells = true;           // parse_lines_cells where the CPU has it (else parse_lines)
};

struct Chunk {
    double *rows = nullptr;              // room for `cap` rows of C values
    size_t cap = 0, n = 0;
    size_t lines = 0;                    // lines consumed (rows and blank lines)
    size_t general = 0;                  // lines read by general_line
    const char *first_blank = nullptr;   // first blank line in the chunk
    bool row_after_blank = false;
    std::string err;                     // first error (message), empty if none
};

size_t line_of(const CsvLayout &L, const char *p)
{
    return L.line0 + 1 + (size_t)std::count(L.text, p, '\n');
}

// The end of the cell at p (before e): the next delimiter outside double quotes ("Force, N" and "1,5"
// are one cell), or the line's end; a quote left open ends the cell at the next delimiter instead.
const char *cell_end(const char *p, const char *e, char delim)
{
    const char *c = p;
    bool quoted = false;
    for (; c < e && *c != '\n' && *c != '\r' && (quoted || *c != delim); ++c) quoted ^= *c == '"';
    if (quoted)
        for (c = p; c < e && *c != delim && *c != '\n' && *c != '\r';) ++c;
    return c;
}

std::string cell_text(const char *p, const char *e, char delim)
{
    return trim(std::string_view(p, (size_t)(cell_end(p, e, delim) - p)));
}

// A decimal comma ("0,25", as spreadsheets in most European locales write numbers, with ';' or tab
// between cells, or quoted): q at the number, r where decimal::parse stopped (at the ','). The cell's
// text up to its delimiter (or closing quote), trailing blanks left out, must hold one ',' and no '.'
// ("1,234.5": a thousands separator, refused); it is read with the ',' as a point (the same correctly
// rounded value as "0.25"). Returns the end of the number, or r (not a number) otherwise.
const char *decimal_comma(const char *q, const char *r, const char *e, bool quoted, char d, double &v, bool &slow)
{
    const char *ce = q;
    while (ce < e && *ce != '\n' && *ce != '\r' && (quoted ? *ce != '"' : *ce != d)) ++ce;
    while (ce > q && (ce[-1] == ' ' || (ce[-1] == '\t' && d != '\t'))) --ce;
    char buf[64];
    const size_t n = (size_t)(ce - q);
    if (n >= sizeof buf || std::count(q, ce, ',') != 1 || std::memchr(q, '.', n)) return r;
    std::memcpy(buf, q, n);
    *std::find(buf, buf + n, ',') = '.';
    buf[n] = '\n';   // decimal::parse reads up to a byte that is no part of a number
    double x = 0;
    bool sl = false;
    if (decimal::parse(buf, buf + n + 1, x, sl) != buf + n) return r;
    v = x;
    slow = sl;
    return ce;
}

// Is the line at b (ending in a '\n' before e) a units row under the header ("s;N;m/s^2", "[V]"): no
// mapped cell a number (also with a decimal comma), at least one text (a quantity without unit: empty)?
bool units_row(const CsvLayout &L, const char *b, const char *e)
{
    const char *le = (const char *)std::memchr(b, '\n', (size_t)(e - b));
    if (!le) return false;
    size_t c = 0, text = 0;
    for (const char *p = b; p <= le && c < L.dest.size(); ++c) {
        const char *a = p;
        p = cell_end(p, le, L.delim);
        std::string cell = trim(std::string_view(a, (size_t)(p - a)));
        if (cell.size() >= 2 && cell.front() == '"' && cell.back() == '"') cell = cell.substr(1, cell.size() - 2);
        ++p;   // past the delimiter (or the '\n': the loop ends)
        if (L.dest[c] < 0 || cell.empty()) continue;
        ++text;
        const char *q = cell.data(), *ce = q + cell.size();
        q += *q == '+';
        double v = 0;
        bool slow = false;
        const char *r = decimal::parse(q, ce, v, slow);
        // the cell is isolated already: no delimiter is left in it (';' lets a quoted "0,25" of a ',' file read)
        if (r && r < ce && *r == ',') r = decimal_comma(q, r, ce, false, L.delim == ',' ? ';' : L.delim, v, slow);
        if (r == ce) return false;   // a number
    }
    return text > 0;
}

// One line at p (a row or a blank line; p at the line start, e just after a
// '\n'): its values into out, or out.err and nullptr. Returns the next line's start.
const char *general_line(const CsvLayout &L, const char *p, const char *e, Chunk &out)
{
    const size_t ncol = L.dest.size(), C = L.C;
    const char d = L.delim;
    const char *ls = p;
    out.general++;
    // a blank line, also one of delimiters only (";;;;": a spreadsheet's export of empty rows): no value
    while (*p == ' ' || *p == '\t' || *p == d) ++p;
    if (*p == '\n' || (*p == '\r' && p[1] == '\n')) {   // blank line
        if (!out.first_blank) out.first_blank = ls;
        p += *p == '\r' ? 2 : 1;
        out.lines++;
        return p;
    }
    if (out.first_blank) out.row_after_blank = true;
    p = ls;
    if (out.n >= out.cap) {   // cannot happen: see the row bound in read_record_csv
        out.err = fmt("'%s': internal error: row count", L.path->c_str());
        return nullptr;
    }
    double *dst = out.rows + out.n * C;   // written in place
    size_t c = 0;
    for (;; ++c) {
        while (*p == ' ' || (*p == '\t' && d != '\t')) ++p;
        if (c >= ncol) {   // beyond the header: only empty trailing fields
            if (*p == d) { ++p; continue; }
            if (*p == '\r' || *p == '\n') break;
            out.err = fmt("'%s' line %zu: ragged row, more than the %zu cells of the header", L.path->c_str(),
                          line_of(L, ls), ncol);
            return nullptr;
        }
        const int dc = L.dest[c];
        if (dc >= 0) {
            const bool quoted = *p == '"';   // "0.25": a quoted number, as some exports write every cell
            const char *q = p + quoted;
            q += *q == '+';
            double v = 0;
            bool slow = false;
            const char *r = decimal::parse(q, e, v, slow);
            if (r && *r == ',' && (quoted || d != ',')) r = decimal_comma(q, r, e, quoted, d, v, slow);
            bool ok = r != nullptr && r != q;
            if (ok && quoted) ok = *r++ == '"';
            if (ok) while (*r == ' ' || (*r == '\t' && d != '\t')) ++r;
            if (!ok || (*r != d && *r != '\n' && *r != '\r')) {
                const std::string cell = cell_text(p, e, d);
                // a long cell is quoted by its start: the message stays one line a person reads
                const std::string shown =
                    cell.size() > 48 ? cell.substr(0, 40) + fmt("... (%zu characters)", cell.size()) : cell;
                out.err = cell.empty()
                              ? fmt("'%s' line %zu, column %s: '' is not a number (empty cell)", L.path->c_str(),
                                    line_of(L, ls), L.names[c].c_str())
                              : fmt("'%s' line %zu, column %s: '%s' is not a number%s", L.path->c_str(),
                                    line_of(L, ls), L.names[c].c_str(), shown.c_str(),
                                    cell.find(',') != std::string::npos && (d != ',' || cell[0] == '"')
                                        ? " (read with ',' as the decimal separator: one ',' and no '.')" : "");
                return nullptr;
            }
            if (!sample_ok(v)) {
                out.err = fmt("'%s' line %zu, column %s: %s", L.path->c_str(), line_of(L, ls), L.names[c].c_str(),
                              sample_fault(v).c_str());
                return nullptr;
            }
            dst[dc] = v;
            p = r;
        } else {
            if (*p == '"') {   // a quoted cell: delimiters in it are text ("J. Smith, shift 2"; "" a quote)
                ++p;
                while (*p != '\n' && !(*p == '"' && p[1] != '"')) p += *p == '"' ? 2 : 1;
                if (*p == '"') ++p;
            }
            while (*p != d && *p != '\n' && *p != '\r') ++p;
        }
        if (*p == d) { ++p; continue; }
        break;
    }
    if (*p == '\r') ++p;
    if (*p != '\n') {
        out.err = fmt("'%s' line %zu: stray carriage return", L.path->c_str(), line_of(L, ls));
        return nullptr;
    }
    ++p;
    // missing trailing cells are fine only for ignored columns
    for (size_t k = c + 1; k < ncol; ++k)
        if (L.dest[k] >= 0) {
            out.err = fmt("'%s' line %zu: ragged row, %zu cells where the header has %zu (column %s missing)",
                          L.path->c_str(), line_of(L, ls), c + 1, ncol, L.names[k].c_str());
            return nullptr;
        }
    out.n++;
    out.lines++;
    return p;
}

// Parse the lines in [b, e) (b at a line start, e just after a '\n') one by one.
void parse_lines(const CsvLayout &L, const char *b, const char *e, Chunk &out)
{
    for (const char *p = b; p < e;)
        if (!(p = general_line(L, p, e, out))) return;
}

#ifdef MSID_CSV_CELLS
// The byte offsets in [p, q) of every delimiter, '\r' and '\n' (64 bytes a step,
// cells::hit_mask64; each step's hits written 8 at a time whatever their count, so
// no branch per hit). pos: room for q - p + 8 offsets. Returns the count.
MSID_CELLS_TARGET size_t structural(const char *p, const char *q, char d, uint32_t *pos)
{
    const size_t len = (size_t)(q - p);
    size_t n = 0, off = 0;
    for (; off + 64 <= len; off += 64) {
        uint64_t m = cells::hit_mask64(p + off, d);
        const size_t cnt = (size_t)__builtin_popcountll(m);
        uint32_t *o = pos + n;
        while (m) {
            for (int k = 0; k < 8; ++k) {   // ctz(m | 2^63): the lowest hit, 63 (unused) once m is 0
                o[k] = (uint32_t)(off + (unsigned)__builtin_ctzll(m | 0x8000000000000000ull));
                m &= m - 1;
            }
            o += 8;
        }
        n += cnt;
    }
    for (; off < len; ++off)
        if (p[off] == d || p[off] == '\n' || p[off] == '\r') pos[n++] = (uint32_t)off;
    return n;
}

// parse_lines with every delimiter found first (structural) and each row of the
// one common shape (every cell -?D+.D+ with at most 15 digits, no spaces, only
// empty cells after the header's columns, LF or CRLF) taken cell by cell from
// those offsets by cells::parse_cell, independently of each other. Any other
// line (blank, ragged, spaces, exponents, '+', an error) goes through
// general_line, which gives it the meaning and the message it has there: the
// values and errors are those of parse_lines, bit for bit (test_csv_rows).
MSID_CELLS_TARGET void parse_lines_cells(const CsvLayout &L, const char *b, const char *e, Chunk &out)
{
    constexpr size_t SUB = (size_t)32 << 10;   // lines scanned at a time (their offsets stay in L1/L2)
    const size_t ncol = L.dest.size(), C = L.C;
    const char d = L.delim;
    std::vector<uint32_t> pos(SUB + 64);
    const char *p = b;
    while (p < e) {
        const char *q = e;
        if ((size_t)(e - p) > SUB) {
            const void *nl = memrchr(p, '\n', SUB);
            if (!nl) {   // a line longer than SUB
                if (!(p = general_line(L, p, e, out))) return;
                continue;
            }
            q = (const char *)nl + 1;
        }
        if (std::memchr(p, '"', (size_t)(q - p))) {   // a quoted cell may hide a delimiter: the general path
            for (const char *s = p; s < q;)
                if (!(s = general_line(L, s, e, out))) return;
            p = q;
            continue;
        }
        const size_t np = structural(p, q, d, pos.data());
        size_t i = 0;
        const char *ls = p;
        while (ls < q) {
            size_t j = i;
            const char *s = ls;
            bool ok = out.n < out.cap;
            double *dst = out.rows + out.n * C;
            for (size_t c = 0; ok && c < ncol; ++c) {
                const char *t = p + pos[j++];   // the cell's end (each line in [p, q) ends in a '\n' of pos)
                ok = *t == d || (c + 1 == ncol && (*t == '\n' || *t == '\r'));
                const int dc = L.dest[c];
                if (ok && dc >= 0) ok = t - b >= 16 && cells::parse_cell(s, (size_t)(t - s), dst[dc], L.point);
                s = t + 1;
            }
            if (ok) {   // the line's end: empty cells beyond the header's, then LF or CRLF
                const char *t = s - 1;
                while (ok && *t == d) {
                    ok = j < np && p + pos[j] == t + 1;
                    t = t + 1;
                    j += ok;
                }
                if (ok && *t == '\r') {
                    ok = j < np && p + pos[j] == t + 1 && t[1] == '\n';
                    t = t + 1;
                    j += ok;
                }
                ok = ok && *t == '\n';
                s = t + 1;
            }
            if (ok) {
                ls = s;
                if (out.first_blank) out.row_after_blank = true;
                out.n++;
                out.lines++;
            } else {   // the general path gives the line its meaning or its message
                if (!(ls = general_line(L, ls, e, out))) return;
                j = i;
                while (j < np && p + pos[j] < ls) ++j;
            }
            i = j;
        }
        p = q;
    }
}
#endif

// Parse the lines in [b, e) (b at a line start, e just after a '\n').
void parse_chunk(const CsvLayout &L, const char *b, const char *e, Chunk &out)
{
#ifdef MSID_CSV_CELLS
    if (L.cells && cells::available()) return parse_lines_cells(L, b, e, out);
#endif
    parse_lines(L, b, e, out);
}

}  // namespace

namespace {

// The file read in blocks of whole lines: next() hands out [p, q), q just
// after a '\n' (a newline is appended to a last line that lacks one); the
// bytes stay valid until the next call. A regular file is mapped one window
// of about 4 MiB at a time (MAP_POPULATE: no copy, no fault per page; the
// window is unmapped when the next is taken), anything else (a pipe) read(2)
// into a buffer. A line longer than the window grows it (to the line's
// length, a constant of the file, not its size).
class LineBlocks {
public:
    static constexpr size_t BLOCK = (size_t)4 << 20;
    explicit LineBlocks(const std::string &path) : path_(path)
    {
        fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
        if (fd_ < 0) throw FileError("cannot open '" + path + "': " + std::strerror(errno));
        struct stat st;
        if (fstat(fd_, &st) == 0 && S_ISREG(st.st_mode)) size_ = (uint64_t)st.st_size;
    }
    ~LineBlocks()
    {
        unmap();
        ::close(fd_);
    }
    LineBlocks(const LineBlocks &) = delete;
    LineBlocks &operator=(const LineBlocks &) = delete;
    uint64_t file_size() const { return size_; }   // 0 when not a regular file (a pipe)

    bool next(const char *&p, const char *&q) { return size_ && mapped_ ? next_mapped(p, q) : next_read(p, q); }

private:
    std::string path_;
    int fd_ = -1;
    // file positions in 64 bits: size_t is 32 on armhf, and a record may be larger than 4 GiB
    uint64_t size_ = 0, pos_ = 0;
    size_t have_ = 0, cut_ = 0, win_ = BLOCK;
    bool eof_ = false, mapped_ = true;
    std::vector<char> buf_;   // read(2) buffer, or the last line of a mapped file lacking its newline
    void *map_ = nullptr;
    size_t map_len_ = 0;

    void unmap()
    {
        if (map_) munmap(map_, map_len_);
        map_ = nullptr;
    }

    bool next_mapped(const char *&p, const char *&q)
    {
        static const size_t page = (size_t)sysconf(_SC_PAGESIZE);
        unmap();
        while (pos_ < size_) {
            const uint64_t off = pos_ & ~(uint64_t)(page - 1);
            const size_t len = (size_t)std::min<uint64_t>(win_, size_ - off);
            void *m = mmap(nullptr, len, PROT_READ, MAP_PRIVATE | MAP_POPULATE, fd_, (off_t)off);
            if (m == MAP_FAILED) {   // a file system without mmap: read(2) from here on
                if (lseek(fd_, (off_t)pos_, SEEK_SET) < 0)
                    throw FileError("cannot read '" + path_ + "': " + std::strerror(errno));
                mapped_ = false;
                return next_read(p, q);
            }
            map_ = m;
            map_len_ = len;
            const char *b = (const char *)m + (size_t)(pos_ - off), *e = (const char *)m + len;
            const void *nl = memrchr(b, '\n', (size_t)(e - b));
            if (nl) {
                p = b;
                q = (const char *)nl + 1;
                pos_ = off + (uint64_t)(q - (const char *)m);
                return true;
            }
            if (off + len == size_) {   // the last line, without a newline
                buf_.assign(b, e);
                buf_.push_back('\n');
                unmap();
                pos_ = size_;
                p = buf_.data();
                q = p + buf_.size();
                return true;
            }
            unmap();
            win_ *= 2;   // a line longer than the window
        }
        return false;
    }

    bool next_read(const char *&p, const char *&q)
    {
        if (buf_.size() < win_ + 1) buf_.resize(win_ + 1);
        if (cut_ < have_) std::memmove(buf_.data(), buf_.data() + cut_, have_ - cut_);
        have_ -= std::min(cut_, have_);
        cut_ = 0;
        for (;;) {
            while (!eof_ && have_ < buf_.size() - 1) {
                const ssize_t k = ::read(fd_, buf_.data() + have_, buf_.size() - 1 - have_);
                if (k < 0 && errno == EINTR) continue;
                if (k < 0) throw FileError("cannot read '" + path_ + "': " + std::strerror(errno));
                if (k == 0) eof_ = true;
                have_ += (size_t)k;
            }
            if (eof_ && have_ && buf_[have_ - 1] != '\n') buf_[have_++] = '\n';   // room: the +1
            if (have_ == 0) return false;
            const void *nl = memrchr(buf_.data(), '\n', have_);
            if (nl) {
                cut_ = (size_t)((const char *)nl - buf_.data()) + 1;
                p = buf_.data();
                q = p + cut_;
                return true;
            }
            buf_.resize(2 * buf_.size());   // a line longer than the buffer
        }
    }
};

}  // namespace

// The header, the layout and the parse state of one CSV file read block by block.
struct CsvStream::Impl {
    LineBlocks in;
    CsvLayout L;
    Record info;                 // the header's fields, no samples
    std::string path;
    const char *b = nullptr, *end = nullptr;   // the next block's text [b, end), b == end: none
    bool have = false;           // a block is pending
    bool done = false;           // the end-of-file checks have run
    bool two = false;            // a block over 1 MiB parsed by two threads
    size_t row_min = 1;          // a row's fewest bytes (the room bound)
    Samples half;                // the second half of a split block
    size_t blank_line = 0, blank_err = 0;   // first blank line; first blank line followed by data
    size_t lines = 0;            // lines before the pending block
    size_t rows = 0, general = 0;
    explicit Impl(const std::string &p) : in(p), path(p) {}
};

CsvStream::CsvStream(const std::string &path, const ColumnMap &cols, bool split, bool cells)
    : p_(std::make_unique<Impl>(path))
{
    Impl &I = *p_;
    LineBlocks &in = I.in;
    const char *t0 = nullptr, *end = nullptr;
    const bool any = in.next(t0, end);
    const char *p = t0;
    if (any && end - t0 >= 3 && (unsigned char)t0[0] == 0xEF && (unsigned char)t0[1] == 0xBB &&
        (unsigned char)t0[2] == 0xBF)
        p += 3;   /* UTF-8 byte order mark, as some spreadsheet exports write */
    // Comment lines before the header ('#' first, as data loggers write their settings): skipped,
    // and counted, so the lines named in messages are the file's
    size_t comments = 0;
    while (any && p < end && *p == '#') {
        p = (const char *)std::memchr(p, '\n', (size_t)(end - p)) + 1;   // every block ends with '\n'
        ++comments;
    }
    const char *hl = p;
    const char *he = any && p < end ? (const char *)std::memchr(p, '\n', (size_t)(end - p)) : p;
    std::string_view header(hl, (size_t)(he - hl));
    if (!header.empty() && header.back() == '\r') header.remove_suffix(1);
    if (trim(header).empty())
        throw Error("'" + path + "' is empty" + (comments ? fmt(" after %zu comment lines", comments) : std::string()) +
                    ": expected a header row with columns u1.. and y1.. (or named columns and " MSID_OPT("columns") ")");
    // Delimiter: the most frequent of ',', ';' and tab in the header (',' on a tie).
    long nc = 0, ns = 0, nt = 0;   // outside quotes ("Force, N";"Acc" is ';'-delimited)
    bool in_q = false;
    for (char ch : header) {
        in_q ^= ch == '"';
        if (!in_q) nc += ch == ',', ns += ch == ';', nt += ch == '\t';
    }
    char delim = ns > nc && ns >= nt ? ';' : (nt > nc && nt > ns ? '\t' : ',');
    if (nc == ns && nc > nt && he + 1 < end) {   // "Time;Force, N": as many ',' as ';' - the next row decides
        const char *n0 = he + 1, *n1 = (const char *)std::memchr(n0, '\n', (size_t)(end - n0));
        if (n1 && std::count(n0, n1, ';') == ns && std::count(n0, n1, ',') != nc) delim = ';';
    }
    CsvLayout &L = I.L;
    L.path = &I.path;
    L.cells = cells;
    L.delim = delim;
    {
        size_t a = 0;
        for (;;) {
            size_t b = (size_t)(cell_end(header.data() + a, header.data() + header.size(), delim) - header.data());
            if (b >= header.size()) b = std::string_view::npos;
            L.names.push_back(trim(header.substr(a, b == std::string_view::npos ? std::string_view::npos : b - a)));
            if (b == std::string_view::npos) break;
            a = b + 1;
        }
        while (L.names.size() > 1 && L.names.back().empty()) L.names.pop_back();   // trailing delimiters
    }
    for (auto &n : L.names)   // quoted header names ("Force")
        if (n.size() >= 2 && n.front() == '"' && n.back() == '"') n = n.substr(1, n.size() - 2);
    Record &r = I.info;
    r.path = path;
    r.file_columns = L.names;
    const std::vector<size_t> src = resolve_columns(path, L.names, cols, true, r.nu, r.ny);
    const size_t C = L.C = r.nu + r.ny;
    L.dest.assign(L.names.size(), -1);
    for (size_t k = 0; k < src.size(); ++k) {
        L.dest[src[k]] = (int)k;
        r.columns.push_back(L.names[src[k]]);
    }
    // A row holds at least max(cells, 2 C) bytes (each mapped number a character and a delimiter
    // or newline): the room a block's rows can need, without a counting pass.
    I.row_min = std::max(L.names.size(), 2 * C);
    I.two = split && std::thread::hardware_concurrency() >= 2;
    I.lines = 1 + comments;   // lines before the next block (comments, the header)
    L.text = t0;              // block 0 counts lines from the file's start
    const char *b = he + 1;
    if (b < end && units_row(L, b, end)) {   // units under the header: skipped, counted in line numbers
        b = (const char *)std::memchr(b, '\n', (size_t)(end - b)) + 1;
        ++I.lines;
    }
    // A ',' in the first data row of a ';' or tab file: decimal commas, which the cell parser then takes
    // as its point (a cell with the other separator goes to the general path, which reads both)
    if (delim != ',' && b < end && std::memchr(b, ',', (size_t)((const char *)std::memchr(b, '\n', (size_t)(end - b)) - b)))
        L.point = ',';
    I.b = b;
    I.end = end;
    I.have = any;
    if (!any) finish_checks();
}

CsvStream::~CsvStream() = default;
const Record &CsvStream::info() const { return p_->info; }
size_t CsvStream::rows() const { return p_->rows; }
size_t CsvStream::general_lines() const { return p_->general; }
bool CsvStream::at_end() const { return p_->done; }
uint64_t CsvStream::file_size() const { return p_->in.file_size(); }

void CsvStream::finish_checks()
{
    Impl &I = *p_;
    I.done = true;
    if (I.blank_err) throw Error(fmt("'%s' line %zu: empty line inside the data", I.path.c_str(), I.blank_err));
    if (I.rows == 0) throw Error("'" + I.path + "' has a header but no samples");
}

size_t CsvStream::max_block_rows() const
{
    const Impl &I = *p_;
    return I.have ? (size_t)(I.end - I.b) / I.row_min + 2 : 0;
}

size_t CsvStream::next(const std::function<double *(size_t max_rows)> &room)
{
    Impl &I = *p_;
    if (!I.have) return 0;
    CsvLayout &L = I.L;
    const size_t C = L.C;
    const char *b = I.b, *end = I.end;
    const size_t bytes = (size_t)(end - b);
    const char *mid = b + bytes / 2;
    mid = I.two && bytes > ((size_t)1 << 20) ? (const char *)std::memchr(mid, '\n', (size_t)(end - mid)) + 1 : end;
    Chunk ch[2];
    ch[0].cap = (size_t)(mid - b) / I.row_min + 1;
    ch[1].cap = (size_t)(end - mid) / I.row_min + 1;
    double *dst = room(ch[0].cap + ch[1].cap);
    ch[0].rows = dst;
    if (mid < end) {
        if (I.half.size() < ch[1].cap * C) I.half.resize(ch[1].cap * C);
        ch[1].rows = I.half.data();
        std::thread th([&] { parse_chunk(L, mid, end, ch[1]); });
        parse_chunk(L, b, mid, ch[0]);
        th.join();
    } else {
        parse_chunk(L, b, end, ch[0]);
    }
    // A bad cell is reported first (the first in the file); an empty line
    // inside the data only when the whole file has no bad cell.
    size_t n = 0;
    for (Chunk &c : ch) {
        if (!c.err.empty()) throw Error(c.err);
        if (I.blank_line && c.n && !I.blank_err) I.blank_err = I.blank_line;
        const size_t fb = c.first_blank ? line_of(L, c.first_blank) : 0;
        if (fb && c.row_after_blank && !I.blank_err) I.blank_err = fb;
        if (fb && !I.blank_line) I.blank_line = fb;
        if (c.n && c.rows != dst + n * C) std::memcpy(dst + n * C, c.rows, c.n * C * sizeof(double));
        n += c.n;
        I.general += c.general;
        I.lines += c.lines;
    }
    I.rows += n;
    I.have = I.in.next(I.b, I.end);
    if (I.have) {
        L.text = I.b;   // both halves count lines from the block's start
        L.line0 = I.lines;
    } else {
        finish_checks();
    }
    return n;
}

Record read_record_csv(const std::string &path, const ColumnMap &cols, bool split, bool cells)
{
    CsvStream s(path, cols, split, cells);
    Record r = s.info();
    const size_t C = r.nu + r.ny;
    // Room by the stream's bound, sized from the file's size (pages never written are never
    // touched: no zero fill), grown for a pipe; each block parsed in place at the end. At first at most
    // an eighth of the address space: on a 32-bit target the bound of a file of a GB or more exceeds what
    // the process can map although its rows may fit (from there the room grows as for a pipe).
    const uint64_t bound = (s.file_size() / std::max<size_t>(2 * C, r.file_columns.size()) + 1) * C;
    r.rows.resize((size_t)std::min<uint64_t>(bound, SIZE_MAX / 8 / sizeof(double)));
    while (!s.at_end()) {
        s.next([&](size_t max_rows) {
            if (r.rows.size() < (r.n_rows + max_rows) * C)
                r.rows.resize(std::max(2 * r.rows.size(), (r.n_rows + max_rows) * C));
            return r.rows.data() + r.n_rows * C;
        });
        r.n_rows = s.rows();
    }
    r.general_lines = s.general_lines();
    r.rows.resize(r.n_rows * C);   // shrinks in place; the untouched tail was never faulted in
    return r;
}

}  // namespace msidrec
