// Binary experiment files -> Record: NumPy .npy (own reader, format 1.0-3.0),
// .npz (a zip of .npy members, stored or deflated; inflated with zlib) and
// MATLAB .mat v5 / v7.3 (libmatio; v7.3 is HDF5, Debian's matio is built
// with it).
//
// Columns of a binary file (the names --columns maps, see README "CSV records"):
//  - a vector variable `name` (n, n x 1 or 1 x n) is one column `name`;
//  - a matrix variable `name` of n samples x C channels gives columns
//    `name:1` .. `name:C` (a matrix with more columns than rows is read as
//    C channels x n samples);
//  - a .npy file holds one unnamed matrix: its columns are `1` .. `C`.
// Without --columns, vectors named u<k> / y<k> (and t/time, ignored) are taken.
#include "binary_detail.hpp"

#include <cctype>
#include <cerrno>
#include <sys/mman.h>
#include <cmath>
#include <cstring>
#include <fcntl.h>
#include "matio_dl.hpp"
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

namespace msidrec {

namespace {


// Parse one .npy image (whole file, or a .npz member) into an Array viewing `buf`.
Array parse_npy(const std::string &where, std::string_view buf, const std::string &name)
{
    const auto *b = (const unsigned char *)buf.data();
    if (buf.size() < 10 || std::memcmp(b, "\x93NUMPY", 6) != 0)
        throw Error("'" + where + "' is not a NumPy .npy array (no \\x93NUMPY magic)");
    const unsigned major = b[6];
    size_t hlen, hoff;
    if (major == 1) { hlen = b[8] | (size_t)b[9] << 8; hoff = 10; }
    else if (major == 2 || major == 3) {
        if (buf.size() < 12) throw Error("'" + where + "': truncated .npy header");
        hlen = b[8] | (size_t)b[9] << 8 | (size_t)b[10] << 16 | (size_t)b[11] << 24; hoff = 12;
    } else throw Error(fmt("'%s': .npy format version %u is not supported", where.c_str(), major));
    if (hoff + hlen > buf.size()) throw Error("'" + where + "': truncated .npy header");
    const std::string h(buf.substr(hoff, hlen));
    auto field = [&](const char *key) -> std::string {
        const size_t k = h.find(std::string("'") + key + "'");
        if (k == std::string::npos) throw Error(fmt("'%s': .npy header has no '%s'", where.c_str(), key));
        size_t v = h.find(':', k);
        if (v == std::string::npos) throw Error(fmt("'%s': bad .npy header", where.c_str()));
        ++v;
        while (v < h.size() && h[v] == ' ') ++v;
        return h.substr(v);
    };
    Array a;
    a.name = name;
    std::string descr = field("descr");
    if (descr.empty() || (descr[0] != '\'' && descr[0] != '"'))
        throw Error("'" + where + "': structured .npy arrays are not supported; save a plain float array (or an .npz of "
                    "one vector per channel)");
    descr = descr.substr(1, descr.find(descr[0], 1) - 1);
    if (descr.size() < 3) throw Error("'" + where + "': bad dtype '" + descr + "'");
    const char endian = descr[0], kind = descr[1];
    const int sz = std::atoi(descr.c_str() + 2);
    const bool ok = (kind == 'f' && (sz == 4 || sz == 8)) ||
                    ((kind == 'i' || kind == 'u') && (sz == 1 || sz == 2 || sz == 4 || sz == 8));
    if (!ok)
        throw Error("'" + where + "': dtype '" + descr + "' is not supported (float32/64 or integers; complex is not)");
    a.kind = kind;
    a.esize = (size_t)sz;
    a.swap = endian == '>' && sz > 1;
    const bool fortran = field("fortran_order").rfind("True", 0) == 0;
    std::string shp = field("shape");
    if (shp.empty() || shp[0] != '(') throw Error("'" + where + "': bad .npy shape");
    shp = shp.substr(1, shp.find(')') - 1);
    // 64-bit sizes on every architecture: a dimension or byte count beyond 32 bits is then refused with the
    // same message on armhf as on x86-64, never truncated to a size_t that a small file can satisfy
    std::vector<uint64_t> dims;
    for (size_t p = 0; p < shp.size();) {
        while (p < shp.size() && (shp[p] == ' ' || shp[p] == ',')) ++p;
        if (p >= shp.size()) break;
        char *e;
        const unsigned long long d = std::strtoull(shp.c_str() + p, &e, 10);
        // not a number: an error (found by fuzz_files: a NUL in the shape kept this loop appending 0s until
        // the 10 s timeout; seed corpus/fuzz_files/regress-npy-shape-not-a-number)
        if (e == shp.c_str() + p || dims.size() >= 8) throw Error("'" + where + "': bad .npy shape");
        dims.push_back((uint64_t)d);
        p = (size_t)(e - shp.c_str());
    }
    if (dims.size() == 1) dims.push_back(1);
    if (dims.size() != 2)
        throw Error(fmt("'%s': a %zu-dimensional array; expected a vector or a samples x channels matrix", where.c_str(),
                        dims.size()));
    const uint64_t R64 = dims[0], C64 = dims[1];
    if (C64 && R64 > UINT64_MAX / C64 / a.esize)   // R * Cc * esize would wrap and pass the size check below
        throw Error(fmt("'%s': the header says %llu x %llu values, more than any file holds", where.c_str(),
                        (unsigned long long)R64, (unsigned long long)C64));
    const uint64_t need = R64 * C64 * a.esize, have = buf.size() - hoff - hlen;
    if (have < need)
        throw Error(fmt("'%s': truncated: the header says %llu x %llu %s (%llu bytes of data) but %llu are there",
                        where.c_str(), (unsigned long long)R64, (unsigned long long)C64, descr.c_str(),
                        (unsigned long long)need, (unsigned long long)have));
    const size_t R = (size_t)R64, Cc = (size_t)C64;   // need <= have: both fit in a size_t
    a.data = b + hoff + hlen;
    // element (r, c) at r*Cc + c (C order) or r + c*R (Fortran order)
    size_t sr = fortran ? 1 : Cc, scc = fortran ? R : 1;
    if (Cc > R) { a.n = Cc; a.C = R; a.si = scc; a.sc = sr; }   // channels x samples
    else { a.n = R; a.C = Cc; a.si = sr; a.sc = scc; }
    return a;
}

// Names of the columns of the arrays: see the file comment.
struct Source { size_t arr, col; };

}  // namespace

Record assemble(const std::string &path, const std::vector<Array> &arrs, const ColumnMap &cols, bool npy_file)
{
    std::vector<std::string> names;
    std::vector<Source> srcs;
    for (size_t k = 0; k < arrs.size(); ++k) {
        const Array &a = arrs[k];
        if (a.C == 1 && !npy_file) { names.push_back(a.name); srcs.push_back({k, 0}); continue; }
        for (size_t c = 0; c < a.C; ++c) {
            names.push_back(npy_file ? std::to_string(c + 1) : a.name + ":" + std::to_string(c + 1));
            srcs.push_back({k, c});
        }
    }
    if (npy_file && cols.empty())
        throw Error(fmt("'%s' holds one %zu x %zu matrix without column names: map its columns (numbered from 1) with "
                        MSID_OPT("columns") " u1=1,y1=2,...", path.c_str(), arrs[0].n, arrs[0].C));
    Record r;
    r.path = path;
    const std::vector<size_t> src = resolve_columns(path, names, cols, false, r.nu, r.ny);
    const size_t C = src.size();
    const size_t n = arrs[srcs[src[0]].arr].n;
    for (size_t k = 0; k < C; ++k) {
        const Array &a = arrs[srcs[src[k]].arr];
        r.columns.push_back(names[src[k]]);
        if (a.n != n)
            throw Error(fmt("'%s': variable '%s' has %zu samples but '%s' has %zu", path.c_str(), names[src[k]].c_str(),
                            a.n, names[src[0]].c_str(), n));
    }
    if (n == 0) throw Error("'" + path + "' holds no samples");
    r.n_rows = n;
    r.rows.resize(n * C);
    // Row by row (one pass over the output); plain little-endian doubles are
    // copied, anything else converted; non-finite values are looked up after.
    std::vector<const Array *> A(C);
    std::vector<const unsigned char *> base(C);
    std::vector<size_t> step(C);
    bool plain = true;
    for (size_t k = 0; k < C; ++k) {
        A[k] = &arrs[srcs[src[k]].arr];
        base[k] = A[k]->data + srcs[src[k]].col * A[k]->sc * A[k]->esize;
        step[k] = A[k]->si * A[k]->esize;
        plain = plain && A[k]->kind == 'f' && A[k]->esize == 8 && !A[k]->swap;
    }
    double *out = r.rows.data();
    bool finite = true;
    for (size_t i = 0; i < n; ++i)
        for (size_t k = 0; k < C; ++k) {
            double v;
            if (plain) std::memcpy(&v, base[k] + i * step[k], 8);
            else v = A[k]->at(i, srcs[src[k]].col);
            out[i * C + k] = v;
            finite = finite && sample_ok(v);
        }
    if (!finite)
        for (size_t i = 0; i < n; ++i)
            for (size_t k = 0; k < C; ++k)
                if (!sample_ok(out[i * C + k]))
                    throw Error(fmt("'%s' row %zu, column %s: %s", path.c_str(), i + 1, names[src[k]].c_str(),
                                    sample_fault(out[i * C + k]).c_str()));
    return r;
}



void check_finite(const Record &r, size_t row0, size_t n)
{
    const size_t C = (size_t)r.nu + r.ny;
    if (row0 > r.n_rows || n > r.n_rows - row0) throw Error("internal error: rows beyond the record");
    const double *x = r.data() + row0 * C;
    // NaN, Inf and |x| > SAMPLE_MAX: the magnitude's bits (sign cleared) above those of SAMPLE_MAX
    // (the bit patterns of non-negative doubles, NaN and Inf last, are ordered as their values).
    // Integer OR-reduction over the bit patterns, no branch per sample, no floating-point compare:
    // |b| + (2^63 - 1 - LIMIT) reaches bit 63 exactly when |b| > LIMIT; and, add and or on 64-bit
    // lanes are SSE2, so the loop vectorises at the x86-64 baseline (a compare of 64-bit lanes is
    // SSE4.1/4.2, which kept the loop scalar)
    uint64_t LIMIT;
    std::memcpy(&LIMIT, &SAMPLE_MAX, sizeof LIMIT);
    const uint64_t ABS = 0x7fffffffffffffffull, LIFT = ABS - LIMIT;
    uint64_t bad = 0;
    const size_t nx = n * C;
    for (size_t i = 0; i < nx; ++i) {
        uint64_t b;
        std::memcpy(&b, x + i, sizeof b);
        bad |= (b & ABS) + LIFT;
    }
    if ((bad >> 63) == 0) return;
    for (size_t i = 0; i < nx; ++i)
        if (!sample_ok(x[i]))
            throw Error(fmt("'%s' row %zu, column %s: %s", r.path.c_str(), row0 + i / C + 1, r.columns[i % C].c_str(),
                            sample_fault(x[i]).c_str()));
}

Record read_record_npy(const std::string &path, const ColumnMap &cols, bool zero_copy, bool defer_finite)
{
    auto buf = std::make_shared<const FileBytes>(path);
    std::vector<Array> arrs{parse_npy(path, std::string_view(buf->data(), buf->size()), "")};
    const Array &a = arrs[0];
    // Zero copy: little-endian float64 in C order, 8-byte aligned, columns mapped 1..C in order.
    bool identity = zero_copy && !cols.empty() && a.kind == 'f' && a.esize == 8 && !a.swap && a.sc == 1 && a.si == a.C &&
                    ((uintptr_t)a.data % alignof(double)) == 0 && cols.map.size() == a.C;
    if (identity) {
        uint32_t nu = 0, ny = 0;
        std::vector<std::string> names;
        for (size_t c = 0; c < a.C; ++c) names.push_back(std::to_string(c + 1));
        const std::vector<size_t> src = resolve_columns(path, names, cols, false, nu, ny);
        for (size_t k = 0; k < src.size(); ++k) identity = identity && src[k] == k;
        if (identity) {
            Record r;
            r.path = path;
            r.nu = nu;
            r.ny = ny;
            r.n_rows = a.n;
            for (size_t k = 0; k < src.size(); ++k) r.columns.push_back(names[k]);
            r.view = reinterpret_cast<const double *>(a.data);
            r.keep = buf;
            if (a.n == 0) throw Error("'" + path + "' holds no samples");
            if (defer_finite) r.finite_unchecked = true;   // the caller scans each block it uses
            else check_finite(r, 0, r.n_rows);
            return r;
        }
    }
    return assemble(path, arrs, cols, true);
}

// [off, off + len) lies inside N bytes, without the wrap-around of off + len (offsets and sizes of a
// zip64 file are 64-bit fields: fuzz_files, 2026-11-23, a zip64 directory at 2^64 - 9 passed
// `z64 + 56 > N` and the reader looked 9 bytes before the file's buffer)
static bool within(uint64_t off, uint64_t len, size_t N) { return off <= N && len <= N - off; }

Record read_record_npz(const std::string &path, const ColumnMap &cols)
{
    const FileBytes z(path);
    const auto *b = (const unsigned char *)z.data();
    const size_t N = z.size();
    // End of central directory: the last "PK\5\6" within 64 KiB + 22 bytes of the end.
    size_t eocd = SIZE_MAX;
    for (size_t k = N >= 22 ? N - 22 : 0; N >= 22; --k) {
        if (le32(b + k) == 0x06054b50u) { eocd = k; break; }
        if (k == 0 || N - k > 65557) break;
    }
    if (eocd == SIZE_MAX) throw Error("'" + path + "' is not an .npz (zip) file: no end-of-central-directory record");
    uint64_t nent = le16(b + eocd + 10), cdoff = le32(b + eocd + 16);
    if ((nent == 0xFFFF || cdoff == 0xFFFFFFFFu) && eocd >= 20 && le32(b + eocd - 20) == 0x07064b50u) {
        const uint64_t z64 = le64(b + eocd - 20 + 8);   // zip64 end of central directory record
        if (!within(z64, 56, N) || le32(b + z64) != 0x06064b50u) throw Error("'" + path + "': bad zip64 directory");
        nent = le64(b + z64 + 32);
        cdoff = le64(b + z64 + 48);
    }
    // every central directory entry takes at least 46 bytes: a larger count is a lie (a zip64
    // record claiming 2^60 entries made reserve() throw; seed corpus/fuzz_files/regress-npz-zip64-entry-count)
    if (nent > N / 46) throw Error(fmt("'%s': corrupt zip directory (%llu entries in %zu bytes)", path.c_str(),
                                       (unsigned long long)nent, N));
    std::vector<std::string> bufs;   // inflated members (kept alive for the Arrays)
    std::vector<Array> arrs;
    bufs.reserve(nent);
    size_t p = cdoff;
    uint64_t members_bytes = 0;   // compressed bytes of the .npy members so far
    for (uint64_t e = 0; e < nent; ++e) {
        if (!within(p, 46, N) || le32(b + p) != 0x02014b50u) throw Error("'" + path + "': corrupt zip central directory");
        const unsigned method = le16(b + p + 10);
        uint64_t csize = le32(b + p + 20), usize = le32(b + p + 24), loff = le32(b + p + 42);
        const size_t fnl = le16(b + p + 28), exl = le16(b + p + 30), cml = le16(b + p + 32);
        if (!within(p, 46 + fnl + exl, N)) throw Error("'" + path + "': corrupt zip central directory");
        std::string fname((const char *)b + p + 46, fnl);
        // zip64 extra field: the 0xFFFFFFFF sizes/offset follow in this order
        for (size_t x = p + 46 + fnl; x + 4 <= p + 46 + fnl + exl;) {
            const unsigned id = le16(b + x), len = le16(b + x + 2);
            // a field claiming more than the extra area holds would have its fields read past it
            if (x + 4 + len > p + 46 + fnl + exl) throw Error("'" + path + "': corrupt zip central directory");
            if (id == 1) {
                size_t q = x + 4;
                if (usize == 0xFFFFFFFFu && q + 8 <= x + 4 + len) { usize = le64(b + q); q += 8; }
                if (csize == 0xFFFFFFFFu && q + 8 <= x + 4 + len) { csize = le64(b + q); q += 8; }
                if (loff == 0xFFFFFFFFu && q + 8 <= x + 4 + len) { loff = le64(b + q); q += 8; }
            }
            x += 4 + len;
        }
        p += 46 + fnl + exl + cml;
        if (fname.size() < 4 || fname.compare(fname.size() - 4, 4, ".npy") != 0) continue;
        const std::string var = fname.substr(0, fname.size() - 4);
        const std::string where = path + "' variable '" + var;   // quoted as '<path>' variable '<var>'
        if (!within(loff, 30, N) || le32(b + loff) != 0x04034b50u) throw Error("'" + where + "': corrupt zip member");
        const size_t data = loff + 30 + le16(b + loff + 26) + le16(b + loff + 28);
        if (!within(data, csize, N)) throw Error("'" + where + "': truncated zip member");
        // members share no bytes: directory entries pointing at one member's data would each inflate
        // it again (21,907 bytes whose 256 entries name one 8 MiB member asked for 2 GiB), so the
        // members' compressed bytes together fit in the file, and what they inflate to in 1032 x it
        members_bytes += csize;
        if (members_bytes > N)
            throw Error(fmt("'%s': corrupt zip: its members claim %llu bytes of data in a file of %zu (members that "
                            "overlap)", path.c_str(), (unsigned long long)members_bytes, N));
        std::string m;
        if (method == 0) {   // stored: parse in place
            arrs.push_back(parse_npy(where, std::string_view((const char *)b + data, csize), var));
            continue;
        } else if (method == 8) {
            // deflate expands at most 1032:1: a larger uncompressed size would size memory from a lie
            // (a 100-byte member claiming 4 GiB; seed corpus/fuzz_files/regress-npz-huge-uncompressed-size)
            if (usize > csize * DEFLATE_MAX_RATIO + 1024)
                throw Error(fmt("'%s': corrupt zip member: it claims %llu bytes inflated from %llu (deflate expands "
                                "at most %llu:1)", where.c_str(), (unsigned long long)usize,
                                (unsigned long long)csize, (unsigned long long)DEFLATE_MAX_RATIO));
            m.resize(usize);
            z_stream zs{};
            if (inflateInit2(&zs, -MAX_WBITS) != Z_OK) throw Error("zlib: inflateInit2 failed");
            zs.next_in = const_cast<Bytef *>(b + data);
            zs.avail_in = (uInt)csize;
            zs.next_out = (Bytef *)&m[0];
            zs.avail_out = (uInt)usize;
            const int rc = inflate(&zs, Z_FINISH);
            const size_t got = zs.total_out;
            inflateEnd(&zs);
            if (rc != Z_STREAM_END || got != usize) throw Error("'" + where + "': corrupt deflated data");
        } else throw Error(fmt("'%s': zip compression method %u is not supported (stored or deflated)", where.c_str(), method));
        bufs.push_back(std::move(m));
        arrs.push_back(parse_npy(where, bufs.back(), var));
    }
    if (arrs.empty()) throw Error("'" + path + "' holds no .npy arrays");
    return assemble(path, arrs, cols, false);
}

// A MATLAB v4 file is a run of records (a 20-byte header: type MOPT, rows, columns, imaginary flag, name
// length; the name; the data). libmatio sizes its work from a header before checking it against the file
// (found by fuzz_files: a 297-byte v4 file kept it clearing memory past libFuzzer's 10 s timeout;
// seed corpus/fuzz_files/regress-mat-v4-header-beyond-file), so each record is checked against the bytes
// the file holds first. v5 files are read by our own code (mat_v5.cpp), v7.3 by libmatio after
// check_mat_hdf5.
static void check_mat_v4(const std::string &path, const unsigned char *b, size_t N)
{
    static const unsigned esize[6] = {8, 4, 4, 2, 2, 1};   // P: double, single, int32, int16, uint16, uint8
    for (size_t p = 0, k = 1; p < N; ++k) {
        if (N - p < 20) throw Error(fmt("'%s': variable %zu of the MATLAB v4 file is truncated", path.c_str(), k));
        uint32_t h[5];
        for (int i = 0; i < 5; ++i) h[i] = le32(b + p + 4 * i);
        if (h[0] >= 1000 && h[0] < 2000)   // M = 1: a big-endian file
            for (int i = 0; i < 5; ++i) h[i] = (uint32_t)b[p + 4 * i] << 24 | (uint32_t)b[p + 4 * i + 1] << 16 |
                                              (uint32_t)b[p + 4 * i + 2] << 8 | b[p + 4 * i + 3];
        const uint32_t P = h[0] / 10 % 10;
        const uint64_t need = (uint64_t)h[4] + (uint64_t)h[1] * h[2] * (P < 6 ? esize[P] : 1) * (h[3] ? 2 : 1);
        if (h[0] >= 2000 || P >= 6 || need > N - p - 20)
            throw Error(fmt("'%s' is not a MATLAB .mat file or is corrupt: variable %zu claims more bytes than the file "
                            "holds", path.c_str(), k));
        p += 20 + need;
    }
}

static std::string lower(std::string s)
{
    for (auto &ch : s) ch = (char)std::tolower((unsigned char)ch);
    return s;
}

namespace {

// v4 and v7.3 through libmatio, variable by variable. A variable's dimensions are checked against what
// the file can hold (the caller) before Mat_VarRead allocates its data: v4 stores it uncompressed
// (check_mat_v4 bounds each record by the file), v7.3 at most deflate's ratio (check_mat_hdf5 bounds
// every dataset before libmatio opens the file).
class MatioFile : public MatReader {
  public:
    MatioFile(const std::string &path, uint64_t holds) : path_(path), holds_(holds)
    {
        M_.LogInitFunc("msid", mat_log);   // matio's messages go to the one error, not to stderr
        mf_ = M_.Open(path.c_str(), MAT_ACC_RDONLY);
        if (!mf_)
            throw Error("'" + path + "' is not a MATLAB .mat file (v4, v5 or v7.3) or is corrupt" +
                        (g_mat_msg.empty() ? std::string() : " (matio: " + g_mat_msg + ")"));
    }
    ~MatioFile() override
    {
        for (auto *x : read_) M_.VarFree(x);
        M_.Close(mf_);
    }
    bool next(MatVarInfo &v) override
    {
        matvar_t *info = M_.VarReadNextInfo(mf_);
        if (!info) return false;
        v = MatVarInfo{};
        v.name = name_ = info->name ? info->name : "";
        v.numeric = info->class_type == MAT_C_DOUBLE || info->class_type == MAT_C_SINGLE ||
                    (info->class_type >= MAT_C_INT8 && info->class_type <= MAT_C_UINT64);
        v.complex = info->isComplex;
        v.logical = info->isLogical;
        v.rank = info->rank;
        v.d0 = info->dims && info->rank > 0 ? info->dims[0] : 0;
        v.d1 = info->dims && info->rank > 1 ? info->dims[1] : 0;
        // class "empty" with elements: an HDF5 dataset (v7.3) whose MATLAB_class attribute libmatio does
        // not read, e.g. h5py's default NUL-padded string (it reads "doubl"), not a non-numeric variable
        v.unclassed = info->class_type == MAT_C_EMPTY && info->rank == 2 && info->dims && v.d0 > 0 && v.d1 > 0;
        const unsigned cs = info->class_type == MAT_C_DOUBLE || info->class_type == MAT_C_INT64 ||
                                    info->class_type == MAT_C_UINT64 ? 8
                            : info->class_type == MAT_C_SINGLE || info->class_type == MAT_C_INT32 ||
                                    info->class_type == MAT_C_UINT32 ? 4
                            : info->class_type == MAT_C_INT16 || info->class_type == MAT_C_UINT16 ? 2 : 1;
        v.claimed = v.d1 && v.d0 > UINT64_MAX / cs / v.d1 ? UINT64_MAX : v.d0 * v.d1 * cs;
        v.holds = holds_;
        M_.VarFree(info);
        return true;
    }
    Array read() override
    {
        matvar_t *v = M_.VarRead(mf_, name_.c_str());
        if (!v || !v->data) {
            if (v) M_.VarFree(v);
            throw Error("'" + path_ + "' variable '" + name_ + "': cannot read its data (truncated or corrupt file)");
        }
        read_.push_back(v);
        Array a;
        a.name = name_;
        switch (v->data_type) {
        case MAT_T_DOUBLE: a.kind = 'f'; a.esize = 8; break;
        case MAT_T_SINGLE: a.kind = 'f'; a.esize = 4; break;
        case MAT_T_INT8: a.kind = 'i'; a.esize = 1; break;
        case MAT_T_UINT8: a.kind = 'u'; a.esize = 1; break;
        case MAT_T_INT16: a.kind = 'i'; a.esize = 2; break;
        case MAT_T_UINT16: a.kind = 'u'; a.esize = 2; break;
        case MAT_T_INT32: a.kind = 'i'; a.esize = 4; break;
        case MAT_T_UINT32: a.kind = 'u'; a.esize = 4; break;
        case MAT_T_INT64: a.kind = 'i'; a.esize = 8; break;
        case MAT_T_UINT64: a.kind = 'u'; a.esize = 8; break;
        default: throw Error("'" + path_ + "' variable '" + name_ + "': unsupported element type");
        }
        const size_t R = v->dims[0], Cc = v->dims[1];
        if (v->nbytes < R * Cc * a.esize) throw Error("'" + path_ + "' variable '" + name_ + "': truncated data");
        a.data = (const unsigned char *)v->data;
        // MATLAB is column-major: (r, c) at r + c*R
        if (Cc > R) { a.n = Cc; a.C = R; a.si = R; a.sc = 1; }
        else { a.n = R; a.C = Cc; a.si = 1; a.sc = R; }
        return a;
    }

  private:
    const Matio &M_ = matio();
    std::string path_, name_;
    uint64_t holds_;
    mat_t *mf_ = nullptr;
    std::vector<matvar_t *> read_;
};

}  // namespace

Record read_record_mat(const std::string &path, const ColumnMap &cols)
{
    std::unique_ptr<MatReader> mr = open_mat_v5(path);   // opens the file (its one error if it cannot)
    if (!mr) {
        const FileBytes f(path);
        const auto *b = (const unsigned char *)f.data();
        if (mat_header_version(b, f.size()) == 0x0200) {   // v7.3: HDF5
            check_mat_hdf5(path, f.size());
            mr = std::make_unique<MatioFile>(path, (uint64_t)f.size() * DEFLATE_MAX_RATIO);
        } else {
            check_mat_v4(path, b, f.size());
            mr = std::make_unique<MatioFile>(path, (uint64_t)f.size());
        }
    }
    std::vector<Array> arrs;
    std::vector<std::string> skipped, all;
    MatVarInfo info;
    while (mr->next(info)) {
        const std::string &name = info.name;
        const bool real2d = info.numeric && info.rank == 2 && !info.complex && !info.logical;
        // nothing is sized from the dimensions (not even the column names below) before they are
        // checked against what the file can hold for the variable
        if (real2d && info.claimed > info.holds)
            throw Error(fmt("'%s' variable '%s' claims %llu x %llu values (%llu bytes) but the file can hold at most "
                            "%llu bytes of it: corrupt or not a MATLAB file", path.c_str(), name.c_str(),
                            (unsigned long long)info.d0, (unsigned long long)info.d1,
                            (unsigned long long)info.claimed, (unsigned long long)info.holds));
        // the column names the variable gives (as assemble() names them), for the message of a
        // mapping that names none; a mapping matches a name as resolve_columns() does, so also
        // case-insensitively: 'force' reads variable Force, as a CSV header or an .npz member
        if (real2d) {
            const size_t C = (size_t)std::min(info.d0, info.d1);
            if (C == 1) all.push_back(name);
            for (size_t c = 0; C != 1 && c < C; ++c) all.push_back(name + ":" + std::to_string(c + 1));
        }
        const std::string lname = lower(name);
        const bool wanted = cols.empty() || [&] {
            for (const auto &e : cols.map) {
                const std::string s = lower(e.second);
                if (s == lname || s.rfind(lname + ":", 0) == 0) return true;
            }
            return false;
        }();
        if (!wanted) continue;
        if (!real2d) {
            const std::string why = info.complex ? "complex" : info.rank != 2 ? fmt("%d-dimensional", info.rank)
                                    : info.unclassed ? MAT_UNCLASSED : "not a numeric array";
            if (!cols.empty())
                throw Error("'" + path + "' variable '" + name + "' is " + why + ": expected a real vector or matrix");
            skipped.push_back(info.unclassed ? name + ": " + why : name);
            continue;
        }
        arrs.push_back(mr->read());
    }
    if (!cols.empty()) {   // a mapped name the file lacks: the message lists every variable, not the read ones
        uint32_t nu = 0, ny = 0;
        resolve_columns(path, all, cols, false, nu, ny);
    }
    if (arrs.empty())
        throw Error("'" + path + "' holds no real numeric vectors or matrices" +
                    (skipped.empty() ? std::string() : " (skipped: " + skipped[0] + (skipped.size() > 1 ? ", ..." : "") + ")"));
    return assemble(path, arrs, cols, false);
}

}  // namespace msidrec
