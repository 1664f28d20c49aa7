// msid_records: experiment records from files as they come: CSV (',', ';' or tab), NumPy
// .npy/.npz and MATLAB .mat (v5, v7.3), and the CSV writer. One entry point, read_experiment(),
// gives every estimator the same samples matrix and column names. No command-line types: errors
// are msidrec::Error (a file's contents: ErrorKind::data; a file that cannot be opened or read:
// ErrorKind::io) and msidrec::ColumnSpecError (a bad column map: ErrorKind::usage).
#pragma once
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <memory>
#include <new>
#include <string>
#include <utility>
#include <vector>

#include "msid_host_error.hpp"

namespace msidrec {

// The largest magnitude of a sample the estimators take. Beyond it the power of a line (|U|^2, |Y|^2
// over the periods) leaves double precision's range: a sample of 1e307 overflowed the FRF's input
// power and one of 1e308 the line DFT, far from where the sample was read. Every reader refuses such a
// sample where it reads it, as it refuses NaN and Inf. The design's amplitudes have the same bound.
constexpr double SAMPLE_MAX = 1e150;

// Whether a sample is within the records' rule: finite and |v| <= SAMPLE_MAX.
inline bool sample_ok(double v) { return std::fabs(v) <= SAMPLE_MAX; }

// What is wrong with a sample outside the rule, in the readers' words (after "'FILE' row R, column C: ").
inline std::string sample_fault(double v)
{
    if (!std::isfinite(v)) return "NaN or Inf is not allowed";
    char b[160];
    std::snprintf(b, sizeof b, "%.6g is beyond the samples' range (|x| <= %g, whose squares double precision "
                               "holds): rescale the record, e.g. change its units", v, SAMPLE_MAX);
    return b;
}

// A problem with a record or its file: one message naming the file, the row and the column.
struct Error : msidutil::Error {
    explicit Error(const std::string &m, msidutil::ErrorKind k = msidutil::ErrorKind::data)
        : msidutil::Error(m, 1, k) {}
};
// A file that cannot be opened or read.
struct FileError : Error {
    explicit FileError(const std::string &m) : Error(m, msidutil::ErrorKind::io) {}
};
// A bad `--columns` / `columns=` mapping (a usage error: exit status 2).
struct ColumnSpecError : msidutil::UsageError {
    explicit ColumnSpecError(const std::string &m) : msidutil::UsageError(m) {}
};

// Allocator of the sample matrices: blocks of 2 MiB and more are 2 MiB
// aligned and marked for transparent huge pages (one page fault per 2 MiB
// instead of per 4 KiB), and resize() does not zero-fill (every element is
// written by the reader before it is read).
void *alloc_big(size_t bytes);
template <class T> struct BigAlloc {
    using value_type = T;
    BigAlloc() = default;
    template <class U> BigAlloc(const BigAlloc<U> &) {}
    T *allocate(size_t n) { return static_cast<T *>(alloc_big(n * sizeof(T))); }
    void deallocate(T *p, size_t) { std::free(p); }
    template <class U, class... A> void construct(U *p, A &&...a)
    {
        if constexpr (sizeof...(A) == 0) ::new ((void *)p) U;
        else ::new ((void *)p) U(std::forward<A>(a)...);
    }
    template <class U> bool operator==(const BigAlloc<U> &) const { return true; }
    template <class U> bool operator!=(const BigAlloc<U> &) const { return false; }
};
using Samples = std::vector<double, BigAlloc<double>>;

// One experiment record: rows of [u_1..u_nu, y_1..y_ny], one per sample.
struct Record {
    std::string path;
    uint32_t nu = 0, ny = 0;
    size_t n_rows = 0;
    Samples rows;                        // n_rows * (nu + ny), row-major (empty only when `view` is set)
    std::vector<std::string> columns;    // nu + ny names in the file, in row order (u1.., y1..)
    // every column the file names, mapped or not (a CSV's header; empty for the binary formats): where
    // `msid frf --lines auto` looks for the excitation's reference r1.. (own_reference_columns)
    std::vector<std::string> file_columns;
    // Zero-copy records (read_experiment(..., zero_copy = true) of a C-order
    // float64 .npy whose columns are u1.., y1.. in order): the samples stay in
    // the mapped file, kept alive by `keep`, and `rows` is empty.
    const double *view = nullptr;
    std::shared_ptr<const void> keep;
    // read with defer_finite: no NaN/Inf scan yet; whoever reads the samples calls
    // check_finite() on every row it takes, before using it (run_frf does, block by block)
    bool finite_unchecked = false;
    // CSV: the lines (rows and blank lines) its general parser read; the others took the cell
    // parser (read_record_csv's `cells`). A count for tests and benchmarks; the values are the same.
    size_t general_lines = 0;
    // The n_rows x (nu + ny) samples, row-major: use this, not `rows`.
    const double *data() const { return view ? view : rows.data(); }
};

// `--columns u1=Force,y1=Acc1,...`: which file column (CSV header name, or a
// variable / matrix column of a binary file) feeds each input and output.
// Empty: the file's own u<k>/y<k> columns are used.
struct ColumnMap {
    std::vector<std::pair<std::string, std::string>> map;   // ("u1", "Force"), ...
    bool inputs_optional = false;   // records without inputs (free responses: msid fit --method multi)
    bool empty() const { return map.empty(); }
};

// Parse a --columns value; throws ColumnSpecError (u<k>/y<k> targets without gaps,
// each target and each source at most once).
ColumnMap parse_column_map(const std::string &spec, bool inputs_optional = false);

// THE reader: an experiment file of any supported format (chosen by the file's
// extension: .npy, .npz, .mat, anything else is CSV). Every problem (missing
// or unreadable file, unknown or duplicate column, ragged row, non-numeric
// cell, NaN/Inf, truncated binary) throws one Error naming the file, the row
// (CSV: line) and the column or variable. See README "CSV records".
// `rows` always holds the samples, unless zero_copy is set: then a plain .npy
// may be used in place (read the samples through data()).
Record read_experiment(const std::string &path, const ColumnMap &cols = {}, bool zero_copy = false);

// Is the file read as CSV by read_experiment() (its name does not end in .npy, .npz or .mat)?
bool is_csv_path(const std::string &path);

// Several experiment files, as read_experiment() of each in turn: the same
// records and, when files are bad, the message of the first bad file in the
// list. Two regular CSV/.npy files or more are read by two threads, one file
// each at a time (and then each CSV by one thread); .npz/.mat or a pipe in
// the list: one after the other.
// `defer_finite` (with zero_copy): a plain .npy used in place is not scanned for NaN/Inf here
// (Record::finite_unchecked); its reader scans each block just before it uses it, while the
// block is in cache (msid frf: the 8 MiB of each file read from memory once instead of twice).
std::vector<Record> read_experiments(const std::vector<std::string> &paths, const ColumnMap &cols = {},
                                     bool zero_copy = false, bool defer_finite = false);

// The reader's check of rows [row0, row0 + n) of a record against the samples' rule (sample_ok: no
// NaN, no Inf, no magnitude beyond SAMPLE_MAX): throws the Error a reader gives ("'FILE' row R,
// column C: NaN or Inf is not allowed", or the magnitude named by sample_fault; the first such cell).
void check_finite(const Record &r, size_t row0, size_t n);

// The CSV reader alone (read_experiment dispatches to it). `split`: a block of
// over 1 MiB is parsed by two threads (the same values either way). `cells`: rows
// of the common shape by the cell parser (decimal::parse_cell) where the CPU has
// it; false: every line by the general parser (the same values and errors).
Record read_record_csv(const std::string &path, const ColumnMap &cols = {}, bool split = true, bool cells = true);

// A CSV record read block by block (about 4 MiB of text at a time): memory that does not grow
// with the record, for a caller that passes each block on (the FRF job's streaming path).
// read_record_csv() is this loop appending every block: the same values, the same messages, in
// the same order (a bad cell is named where the stream reaches it; an empty line inside the data
// once the whole file has no bad cell, when the last block is read).
class CsvStream {
public:
    // Opens the file and reads its header; throws Error (FileError, ColumnSpecError) as read_record_csv.
    CsvStream(const std::string &path, const ColumnMap &cols = {}, bool split = true, bool cells = true);
    ~CsvStream();
    CsvStream(const CsvStream &) = delete;
    CsvStream &operator=(const CsvStream &) = delete;
    // path, nu, ny, columns, file_columns of the record (no samples: n_rows 0, rows empty)
    const Record &info() const;
    // Parses the next block. `room(max_rows)` returns room for max_rows rows of nu + ny doubles
    // (max_rows <= max_block_rows()); the block's n rows are written there, row-major, and n is
    // returned (0 is possible: a block of blank lines). After the last block the end-of-file
    // checks run (an empty line inside the data, no samples at all: Error) and at_end() is true.
    size_t next(const std::function<double *(size_t max_rows)> &room);
    bool at_end() const;
    size_t max_block_rows() const;   // the next block's room bound (0 at the end)
    size_t rows() const;             // rows read so far
    size_t general_lines() const;    // as Record::general_lines
    uint64_t file_size() const;      // bytes (0 for a pipe)

private:
    struct Impl;
    std::unique_ptr<Impl> p_;
    void finish_checks();
};

// Format rows (n x cols) with a header; values printed to round-trip exactly.
std::string format_csv(const std::vector<std::string> &header, const double *rows, size_t n, size_t cols);

// ---- shared by the format readers (csv_io.cpp, array_io.cpp) ----

// A named source column in a file: `name` as shown to users.
// Resolve the u/y assignment from the available names: with a map, each
// mapped source must exist (else Error listing what the file holds); without,
// names u<k>/y<k> (case-insensitive) are taken, names in `ignorable` skipped,
// anything else is an error when `strict`. Returns per destination column
// (u1..u_nu, y1..y_ny) the index into `names`; sets nu, ny.
std::vector<size_t> resolve_columns(const std::string &path, const std::vector<std::string> &names,
                                    const ColumnMap &cols, bool strict, uint32_t &nu, uint32_t &ny);

// Is this a time/index column name (t, time, n, sample, index; case-insensitive)?
bool is_time_name(const std::string &name);

// A whole file's bytes, mapped read-only (no copy); read into memory when it
// cannot be mapped (a pipe). Throws Error naming the file.
class FileBytes {
public:
    explicit FileBytes(const std::string &path);
    ~FileBytes();
    FileBytes(const FileBytes &) = delete;
    FileBytes &operator=(const FileBytes &) = delete;
    const char *data() const { return p_; }
    size_t size() const { return n_; }

private:
    const char *p_ = nullptr;
    size_t n_ = 0;
    std::string own_;
    void *map_ = nullptr;
};

// Binary readers (array_io.cpp).
Record read_record_npy(const std::string &path, const ColumnMap &cols, bool zero_copy, bool defer_finite = false);
Record read_record_npz(const std::string &path, const ColumnMap &cols);
Record read_record_mat(const std::string &path, const ColumnMap &cols);

}  // namespace msidrec
