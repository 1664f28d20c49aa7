// What the binary readers (.npy, .npz, .mat) share inside msid_records: the array a variable's bytes
// are viewed as, the assembly of arrays into a Record, the .mat readers' common interface and the
// little-endian loads.
#pragma once
#include <cstdint>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "msid_mat_values.hpp"
#include "records_detail.hpp"

namespace msidrec {

// One source array: name, dims (rows x cols in samples x channels after any
// transpose), and an element accessor over raw bytes.
struct Array {
    std::string name;      // variable name ("" for .npy)
    size_t n = 0, C = 0;   // samples, channels
    // element (i, c) as double, from the raw buffer
    const unsigned char *data = nullptr;
    size_t esize = 8;
    char kind = 'f';       // 'f' float, 'i' signed, 'u' unsigned
    bool swap = false;     // big-endian
    size_t si = 0, sc = 0; // element strides (in elements) for sample and channel
    double at(size_t i, size_t c) const
    {
        const unsigned char *p = data + (i * si + c * sc) * esize;
        unsigned char b[8];
        for (size_t k = 0; k < esize; ++k) b[k] = swap ? p[esize - 1 - k] : p[k];
        switch (kind) {
        case 'f': if (esize == 8) { double v; std::memcpy(&v, b, 8); return v; }
                  else { float v; std::memcpy(&v, b, 4); return v; }
        case 'i': switch (esize) {
                  case 1: { int8_t v; std::memcpy(&v, b, 1); return v; }
                  case 2: { int16_t v; std::memcpy(&v, b, 2); return v; }
                  case 4: { int32_t v; std::memcpy(&v, b, 4); return v; }
                  default: { int64_t v; std::memcpy(&v, b, 8); return (double)v; } }
        default: switch (esize) {
                  case 1: return b[0];
                  case 2: { uint16_t v; std::memcpy(&v, b, 2); return v; }
                  case 4: { uint32_t v; std::memcpy(&v, b, 4); return v; }
                  default: { uint64_t v; std::memcpy(&v, b, 8); return (double)v; } }
        }
    }
};

// The Record of the columns `cols` maps from `arrs` (all of one sample count); `npy_file`: one unnamed
// matrix whose columns are named 1..C. Throws Error naming `path`.
Record assemble(const std::string &path, const std::vector<Array> &arrs, const ColumnMap &cols, bool npy_file);

inline uint32_t le32(const unsigned char *p) { return p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24; }
inline uint16_t le16(const unsigned char *p) { return (uint16_t)(p[0] | p[1] << 8); }
inline uint64_t le64(const unsigned char *p) { return le32(p) | (uint64_t)le32(p + 4) << 32; }

// deflate's largest expansion: at most 1032 bytes out per byte in (zlib's technical details); every
// size that compressed bytes stand for is bounded by this times the compressed bytes
constexpr uint64_t DEFLATE_MAX_RATIO = 1032;

// One variable of a .mat file as its header describes it, before any of its data is read.
struct MatVarInfo {
    std::string name;
    bool numeric = false;     // a double, single or integer class
    bool complex = false, logical = false;
    bool unclassed = false;   // v7.3: a dataset without a MATLAB class libmatio reads
    int rank = 0;
    uint64_t d0 = 0, d1 = 0;  // its first two dimensions
    uint64_t claimed = 0;     // bytes its dimensions claim (elements x the element size)
    uint64_t holds = 0;       // the most bytes the file can hold for it (claimed > holds: one error)
};

// A .mat file variable by variable: next() describes the next variable (false at the end), read()
// returns the one next() described, its bytes kept alive by the reader. Throws Error naming the file.
class MatReader {
  public:
    virtual ~MatReader() = default;
    virtual bool next(MatVarInfo &v) = 0;
    virtual Array read() = 0;
    // The variable next() described, whole (read_mat_values); v5 only.
    virtual MatValue read_value() { throw Error("reading a whole variable needs a MATLAB v5 file"); }
};

// The version of a v5/v7.3 header (a 128-byte header ending in "IM", or "MI" when written big-endian:
// 0x0100 v5, 0x0200 v7.3), 0 when the file has none. libmatio reads any other file, an "IM" header with
// another version included, as v4 (fuzz_files, 2026-11-23: version 0 and a v4 name length of 2 GB).
unsigned mat_header_version(const unsigned char *b, size_t N);

// The MATLAB v5 reader (our own: every size it allocates is checked against the bytes present), or
// nullptr when `path` has no v5 header (v4 and v7.3 go through libmatio).
std::unique_ptr<MatReader> open_mat_v5(const std::string &path);

// v7.3 (HDF5) before libmatio opens it: every dataset's and attribute's elements x element size
// against what the file can hold; throws Error naming the file, the object and the size it claims.
void check_mat_hdf5(const std::string &path, size_t file_bytes);

// Why a v7.3 dataset with elements but no MATLAB class libmatio reads is not read (mat_hdf5.cpp).
extern const char MAT_UNCLASSED[];

// read_mat_values of a v7.3 file (mat_values_v73.cpp): check_mat_hdf5 first, then the named variables
// through libmatio, each one's claimed size checked before it is read.
std::vector<MatValue> read_mat_values_v73(const std::string &path, size_t file_bytes, const std::vector<std::string> &names);

}  // namespace msidrec
