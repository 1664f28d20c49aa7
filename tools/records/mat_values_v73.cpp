// Whole variables of a MATLAB v7.3 (HDF5) .mat file (read_mat_values; an idfrd-shaped FRF), through
// libmatio after check_mat_hdf5 has bounded every dataset, attribute and reference the file holds (at
// most deflate's ratio times the file's size), and each variable's claimed size is checked again
// against that bound before Mat_VarRead allocates it. What an idfrd-shaped file holds is read: numeric
// arrays of any rank (double, single or integer; complex as MATLAB stores it, a {real, imag} compound),
// char rows (uint16 code units), and cell arrays of char rows. Anything else named is one Error.
#include "binary_detail.hpp"
#include "matio_dl.hpp"

#include <algorithm>
#include <memory>

namespace msidrec {

namespace {

// One element of a numeric matvar as a double.
double element(const void *data, matio_types t, size_t k)
{
    switch (t) {
    case MAT_T_DOUBLE: return static_cast<const double *>(data)[k];
    case MAT_T_SINGLE: return static_cast<const float *>(data)[k];
    case MAT_T_INT8: return static_cast<const int8_t *>(data)[k];
    case MAT_T_UINT8: return static_cast<const uint8_t *>(data)[k];
    case MAT_T_INT16: return static_cast<const int16_t *>(data)[k];
    case MAT_T_UINT16: return static_cast<const uint16_t *>(data)[k];
    case MAT_T_INT32: return static_cast<const int32_t *>(data)[k];
    case MAT_T_UINT32: return static_cast<const uint32_t *>(data)[k];
    case MAT_T_INT64: return (double)static_cast<const int64_t *>(data)[k];
    case MAT_T_UINT64: return (double)static_cast<const uint64_t *>(data)[k];
    default: return 0;
    }
}

size_t element_size(matio_types t)
{
    switch (t) {
    case MAT_T_DOUBLE: case MAT_T_INT64: case MAT_T_UINT64: return 8;
    case MAT_T_SINGLE: case MAT_T_INT32: case MAT_T_UINT32: return 4;
    case MAT_T_INT16: case MAT_T_UINT16: case MAT_T_UTF16: return 2;
    case MAT_T_INT8: case MAT_T_UINT8: case MAT_T_UTF8: return 1;
    default: return 0;
    }
}

bool numeric_class(matio_classes c)
{
    return c == MAT_C_DOUBLE || c == MAT_C_SINGLE || (c >= MAT_C_INT8 && c <= MAT_C_UINT64);
}

struct Reader {
    const Matio &M = matio();
    std::string path;
    mat_t *mf = nullptr;
    ~Reader() { if (mf) M.Close(mf); }

    Error bad(const std::string &name, const std::string &what) const
    {
        return Error("'" + path + "' variable '" + name + "': " + what);
    }

    // A char matvar's text (code units above 127 as '?', as the v5 reader gives them): one row, as the v5
    // reader takes it (a char matrix's rows would run together, column-major).
    std::string text(const matvar_t *v, const std::string &name) const
    {
        if (v->rank != 2 || !v->dims || (v->dims[0] > 1 && v->dims[1] > 0)) throw bad(name, "text that is not one row");
        const size_t es = element_size(v->data_type), n = v->nbytes / (es ? es : 1);
        if (!es || v->data_type == MAT_T_DOUBLE || v->data_type == MAT_T_SINGLE)
            throw bad(name, "a char array of an unexpected element type");
        std::string s;
        for (size_t k = 0; k < n; ++k) {
            const double c = element(v->data, v->data_type, k);
            s += c >= 0 && c < 128 ? (char)c : '?';
        }
        return s;
    }

    MatValue value(const matvar_t *v, const std::string &name) const
    {
        MatValue x;
        x.name = name;
        for (int r = 0; r < v->rank; ++r) x.dims.push_back(v->dims[r]);
        // the element count (libmatio's dims are size_t), which must not wrap: on a 32-bit build two
        // dimensions of 65536 would give 0 elements, an empty variable of a file that says otherwise
        size_t n = 1;
        for (uint64_t d : x.dims)
            if (__builtin_mul_overflow(n, (size_t)d, &n)) throw bad(name, "more elements than memory holds");
        if (numeric_class(v->class_type)) {
            x.kind = MatValue::Numeric;
            const size_t es = element_size(v->data_type);
            if (!es || v->data_type == MAT_T_UTF8 || v->data_type == MAT_T_UTF16) throw bad(name, "unsupported element type");
            const void *re = v->data, *im = nullptr;
            if (v->isComplex) {
                const auto *z = static_cast<const mat_complex_split_t *>(v->data);
                re = z->Re;
                im = z->Im;
            }
            // libmatio's nbytes covers one part of a complex variable
            if (n && (!re || (v->isComplex && !im) || v->nbytes / es < n)) throw bad(name, "truncated data");
            x.re.resize(n);
            for (size_t k = 0; k < n; ++k) x.re[k] = element(re, v->data_type, k);
            if (im) {
                x.im.resize(n);
                for (size_t k = 0; k < n; ++k) x.im[k] = element(im, v->data_type, k);
            }
        } else if (v->class_type == MAT_C_CHAR) {
            x.kind = MatValue::Char;
            x.text = v->data ? text(v, name) : std::string();
        } else if (v->class_type == MAT_C_CELL) {
            x.kind = MatValue::Cells;
            matvar_t *const *cell = static_cast<matvar_t *const *>(v->data);
            for (size_t k = 0; k < n; ++k) {
                if (!cell || !cell[k] || cell[k]->class_type != MAT_C_CHAR) throw bad(name, "a cell that is not a char row");
                x.cells.push_back(cell[k]->data ? text(cell[k], name) : std::string());
            }
        } else {
            x.kind = MatValue::Other;
        }
        return x;
    }
};

}  // namespace

std::vector<MatValue> read_mat_values_v73(const std::string &path, size_t file_bytes, const std::vector<std::string> &names)
{
    check_mat_hdf5(path, file_bytes);
    const uint64_t holds = (uint64_t)file_bytes * DEFLATE_MAX_RATIO;
    Reader R;
    R.path = path;
    R.M.LogInitFunc("msid", mat_log);   // matio's messages go to the one error, not to stderr
    R.mf = R.M.Open(path.c_str(), MAT_ACC_RDONLY);
    if (!R.mf)
        throw Error("'" + path + "' is not a MATLAB v7.3 .mat file or is corrupt" +
                    (g_mat_msg.empty() ? std::string() : " (matio: " + g_mat_msg + ")"));
    std::vector<MatValue> out;
    while (matvar_t *info = R.M.VarReadNextInfo(R.mf)) {
        const std::string name = info->name ? info->name : "";
        uint64_t claimed = 1;
        for (int r = 0; r < info->rank && info->dims; ++r)
            claimed = info->dims[r] && claimed > UINT64_MAX / 16 / info->dims[r] ? UINT64_MAX : claimed * info->dims[r];
        const bool want = std::find(names.begin(), names.end(), name) != names.end();
        // elements but no class: a MATLAB_class attribute libmatio does not read (h5py's default)
        const bool unclassed = info->class_type == MAT_C_EMPTY && info->rank > 0 && info->dims &&
                               std::all_of(info->dims, info->dims + info->rank, [](size_t d) { return d > 0; });
        R.M.VarFree(info);
        if (!want) continue;
        if (unclassed) throw R.bad(name, MAT_UNCLASSED);
        // at most 16 bytes an element (a complex double) before libmatio sizes anything from it
        if (claimed != UINT64_MAX) claimed *= 16;
        if (claimed > holds)
            throw R.bad(name, "claims " + std::to_string(claimed) + " bytes, more than the file can hold (" +
                                  std::to_string(holds) + ")");
        std::unique_ptr<matvar_t, void (*)(matvar_t *)> v(R.M.VarRead(R.mf, name.c_str()), R.M.VarFree);
        if (!v) throw R.bad(name, "cannot read it (truncated or corrupt file)");
        out.push_back(R.value(v.get(), name));
    }
    return out;
}

}  // namespace msidrec
