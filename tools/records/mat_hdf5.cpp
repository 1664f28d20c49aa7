// MATLAB v7.3 (HDF5) before libmatio reads it. libmatio allocates from an HDF5 object's dataspace
// before reading anything: a cell array's element count (twice, in Mat_VarReadNextInfo, for every
// variable, read or not), a numeric dataset's elements x class size (Mat_VarRead), a MATLAB_class
// attribute's string size, a struct's field-name count. A dataset's dataspace says nothing of the bytes
// behind it (a chunked dataset never written reads as its fill value), so a small file can claim
// terabytes. Every object reachable by a link is checked first, through HDF5 itself (the library
// libmatio links, found by dlsym on libmatio's handle): a dataset may claim at most deflate's ratio
// times the file's size (MATLAB compresses v7.3 datasets with deflate), an attribute (stored whole, in
// its object's header) at most the file's size. An external link (to another file) is refused. A cell
// array is a dataset of object references, which libmatio follows while it lists the variables; an
// object they point at need not be linked anywhere, so every reference is followed here too (each
// object once) and its target checked the same way. The references of all cells together are at most
// the file's size / 8 (each element is an object of its own in a MATLAB file; libmatio's memory and
// time grow with their number, not with the objects they point at).
#include "binary_detail.hpp"
#include "matio_dl.hpp"

#include <dlfcn.h>
#include <unordered_set>

namespace msidrec {

namespace {

// The HDF5 1.10/1.12 C API, as far as used here (hid_t is 64-bit since 1.10; H5P_DEFAULT and
// H5E_DEFAULT are 0, H5F_ACC_RDONLY 0; a link's info starts with its type in both versions).
using hid_t = int64_t;
using herr_t = int;
using hsize_t = unsigned long long;
using hssize_t = long long;
using haddr_t = uint64_t;   // hobj_ref_t: an object reference is the object's address
constexpr int H5_INDEX_NAME = 0, H5_ITER_NATIVE = 2, H5I_GROUP = 2, H5I_DATASET = 5, H5L_TYPE_HARD = 0,
              H5L_TYPE_SOFT = 1, H5T_COMPOUND = 6, H5T_REFERENCE = 7, H5R_OBJECT = 0;
using LinkCb = herr_t (*)(hid_t, const char *, const void *, void *);
using AttrCb = herr_t (*)(hid_t, const char *, const void *, void *);

struct H5 {
    herr_t (*open)();
    herr_t (*eset_auto2)(hid_t, void *, void *);
    hid_t (*fopen)(const char *, unsigned, hid_t);
    herr_t (*fclose)(hid_t);
    herr_t (*lvisit)(hid_t, int, int, LinkCb, void *);
    hid_t (*oopen)(hid_t, const char *, hid_t);
    herr_t (*oclose)(hid_t);
    int (*iget_type)(hid_t);
    hid_t (*dget_space)(hid_t);
    hid_t (*dget_type)(hid_t);
    herr_t (*aiterate2)(hid_t, int, int, hsize_t *, AttrCb, void *);
    hid_t (*aopen)(hid_t, const char *, hid_t);
    hid_t (*aget_space)(hid_t);
    hid_t (*aget_type)(hid_t);
    herr_t (*aclose)(hid_t);
    hssize_t (*sget_npoints)(hid_t);
    herr_t (*sclose)(hid_t);
    size_t (*tget_size)(hid_t);
    herr_t (*tclose)(hid_t);
    int (*tget_class)(hid_t);
    int (*tequal)(hid_t, hid_t);
    herr_t (*dread)(hid_t, hid_t, hid_t, hid_t, hid_t, void *);
    hid_t (*rdereference2)(hid_t, hid_t, int, const void *);
    int (*tget_nmembers)(hid_t);
    char *(*tget_member_name)(hid_t, unsigned);
    herr_t (*free_memory)(void *);
    const hid_t *std_ref_obj;   // H5T_STD_REF_OBJ, set by H5open
};

const H5 &h5()
{
    static H5 h{};
    static bool loaded = false;
    if (loaded) return h;
    void *lib = matio().lib;
    auto sym = [&](auto &fn, std::initializer_list<const char *> names) {
        for (const char *n : names)
            if ((fn = reinterpret_cast<std::remove_reference_t<decltype(fn)>>(dlsym(lib, n)))) return;
        throw Error(std::string("reading a v7.3 .mat file needs HDF5's ") + *names.begin() + ", which libmatio does not bring");
    };
    sym(h.open, {"H5open"});
    sym(h.eset_auto2, {"H5Eset_auto2"});
    sym(h.fopen, {"H5Fopen"});
    sym(h.fclose, {"H5Fclose"});
    sym(h.lvisit, {"H5Lvisit2", "H5Lvisit"});   // 1.12 renamed it; the callback's shape is the same
    sym(h.oopen, {"H5Oopen"});
    sym(h.oclose, {"H5Oclose"});
    sym(h.iget_type, {"H5Iget_type"});
    sym(h.dget_space, {"H5Dget_space"});
    sym(h.dget_type, {"H5Dget_type"});
    sym(h.aiterate2, {"H5Aiterate2"});
    sym(h.aopen, {"H5Aopen"});
    sym(h.aget_space, {"H5Aget_space"});
    sym(h.aget_type, {"H5Aget_type"});
    sym(h.aclose, {"H5Aclose"});
    sym(h.sget_npoints, {"H5Sget_simple_extent_npoints"});
    sym(h.sclose, {"H5Sclose"});
    sym(h.tget_size, {"H5Tget_size"});
    sym(h.tclose, {"H5Tclose"});
    sym(h.tget_class, {"H5Tget_class"});
    sym(h.tequal, {"H5Tequal"});
    sym(h.dread, {"H5Dread"});
    sym(h.rdereference2, {"H5Rdereference2"});
    sym(h.tget_nmembers, {"H5Tget_nmembers"});
    sym(h.tget_member_name, {"H5Tget_member_name"});
    sym(h.free_memory, {"H5free_memory"});
    sym(h.std_ref_obj, {"H5T_STD_REF_OBJ_g"});
    loaded = true;
    return h;
}

struct Walk {
    const H5 &h;
    uint64_t dataset_max, attr_max;
    std::string object, what;        // the first object over its bound, and why (empty: none)
    std::vector<std::pair<haddr_t, std::string>> refs;   // objects references point at, still to check,
                                                         // and the linked object whose references led there
    std::unordered_set<haddr_t> followed;   // objects already reached through a reference
    hid_t file = -1;
    // Object references (cell elements) in all the file's reference datasets, and their bound: the
    // file's size / 8. libmatio allocates a variable (about 200 bytes) and reads the target's header for
    // every element of every cell while it lists the variables, even when the elements refer to one
    // object; a compressed dataset of 2^23 equal references (a 119 kB file) took 3.5 GB and 16 minutes.
    // MATLAB writes each cell element as an object of its own (a header of more than 8 bytes in the
    // file), so a file it wrote never holds more references than this.
    uint64_t refs_seen = 0, refs_max = 0;
};

// Bytes a dataspace x datatype claims (saturating); 0 when either cannot be read.
uint64_t claimed(const H5 &h, hid_t space, hid_t type)
{
    const hssize_t n = space >= 0 ? h.sget_npoints(space) : -1;
    const size_t s = type >= 0 ? h.tget_size(type) : 0;
    if (space >= 0) h.sclose(space);
    if (type >= 0) h.tclose(type);
    if (n <= 0 || s == 0) return 0;
    return (uint64_t)n > UINT64_MAX / s ? UINT64_MAX : (uint64_t)n * s;
}

herr_t on_attr(hid_t obj, const char *name, const void *, void *data)
{
    auto &w = *static_cast<Walk *>(data);
    const hid_t a = w.h.aopen(obj, name, 0);
    if (a < 0) return 0;
    const uint64_t c = claimed(w.h, w.h.aget_space(a), w.h.aget_type(a));
    w.h.aclose(a);
    if (c <= w.attr_max) return 0;
    w.what = fmt("has an attribute '%s' that claims %llu bytes, more than the file's %llu", name, (unsigned long long)c,
                 (unsigned long long)w.attr_max);
    return 1;   // stops the walk
}

// A compound dataset type is MATLAB's complex: two members named "real" and "imag". libmatio reads a
// compound by those names without checking that they are there, and fills the variable with whatever
// memory held (h5py's default complex128 names them "r" and "i"). Empty when it is one, else why not.
std::string not_matlab_complex(const H5 &h, hid_t type)
{
    const int n = h.tget_nmembers(type);
    std::string names;
    bool ok = n == 2;
    for (int k = 0; k < n && k < 8; ++k) {
        char *m = h.tget_member_name(type, (unsigned)k);
        const std::string name = m ? m : "";
        if (m) h.free_memory(m);
        names += (k ? ", '" : "'") + name + "'";
        ok = ok && name == (k == 0 ? "real" : "imag");
    }
    return ok ? std::string() : fmt("is a compound of %d members (%s): MATLAB's complex has 'real' and 'imag'", n, names.c_str());
}

// A dataset's bytes against the bound, its object references queued, the attributes of a dataset or
// group against theirs; false (w.what set) on the first that claims more, or on a compound that is not
// MATLAB's complex.
bool check_object(Walk &w, hid_t o, const std::string &via)
{
    const int t = w.h.iget_type(o);
    if (t == H5I_DATASET) {
        const hid_t type = w.h.dget_type(o);
        if (type >= 0 && w.h.tget_class(type) == H5T_COMPOUND) {
            w.what = not_matlab_complex(w.h, type);
            if (!w.what.empty()) {
                w.h.tclose(type);
                return false;
            }
        }
        const bool refs = type >= 0 && w.h.tget_class(type) == H5T_REFERENCE && w.h.tequal(type, *w.h.std_ref_obj) > 0;
        const hid_t space = w.h.dget_space(o);
        const hssize_t n = space >= 0 ? w.h.sget_npoints(space) : 0;
        const uint64_t c = claimed(w.h, space, type);
        if (c > w.dataset_max) {
            w.what = fmt("claims %llu bytes, more than %llu x the file's %llu bytes can hold", (unsigned long long)c,
                         (unsigned long long)DEFLATE_MAX_RATIO, (unsigned long long)w.attr_max);
            return false;
        }
        if (refs && n > 0) {
            // Every reference must be an object of its own in the file, so all cells together are bounded
            // by the file's size; the n x 8 bytes read below are then bounded too.
            if ((w.refs_seen += (uint64_t)n) > w.refs_max) {
                w.what = fmt("holds %llu cell elements (object references; %llu in the file so far), more than the "
                             "file's %llu bytes can hold as objects of their own",
                             (unsigned long long)n, (unsigned long long)w.refs_seen, (unsigned long long)w.attr_max);
                return false;
            }
            std::vector<haddr_t> r((size_t)n);
            if (w.h.dread(o, *w.h.std_ref_obj, 0, 0, 0, r.data()) >= 0)
                for (haddr_t a : r)
                    if (a && a != ~(haddr_t)0) w.refs.emplace_back(a, via);
        }
    }
    if (t == H5I_DATASET || t == H5I_GROUP) {
        hsize_t idx = 0;
        w.h.aiterate2(o, H5_INDEX_NAME, H5_ITER_NATIVE, &idx, on_attr, &w);
    }
    return w.what.empty();
}

herr_t on_link(hid_t group, const char *name, const void *info, void *data)
{
    auto &w = *static_cast<Walk *>(data);
    int ltype;
    std::memcpy(&ltype, info, sizeof ltype);   // H5L_info_t / H5L_info2_t: the link's type comes first
    if (ltype != H5L_TYPE_HARD && ltype != H5L_TYPE_SOFT) {
        w.object = name;
        w.what = "is a link to another file (not read)";
        return 1;
    }
    const hid_t o = w.h.oopen(group, name, 0);
    if (o < 0) return 0;   // a dangling soft link: nothing to read
    const bool ok = check_object(w, o, name);
    w.h.oclose(o);
    if (ok) return 0;
    w.object = name;
    return 1;
}

// Every object a reference points at, each once (references may form cycles).
void follow_references(Walk &w)
{
    while (w.what.empty() && !w.refs.empty()) {
        const haddr_t a = w.refs.back().first;
        const std::string via = std::move(w.refs.back().second);
        w.refs.pop_back();
        if (!w.followed.insert(a).second) continue;
        const hid_t o = w.h.rdereference2(w.file, 0, H5R_OBJECT, &a);
        if (o < 0) continue;   // a reference to nothing: libmatio fails on it with its own message
        if (!check_object(w, o, via)) {
            w.object = via;
            w.what = "refers to an object that " + w.what;
        }
        w.h.oclose(o);
    }
}

}  // namespace

const char MAT_UNCLASSED[] =
    "an array without a MATLAB class that libmatio reads (a v7.3 dataset whose MATLAB_class attribute is not a "
    "NUL-terminated string such as 'double', as h5py writes it by default; write it with MATLAB, hdf5storage, "
    "scipy.io.savemat or as .npz)";

void check_mat_hdf5(const std::string &path, size_t file_bytes)
{
    const H5 &h = h5();
    h.open();
    h.eset_auto2(0, nullptr, nullptr);   // HDF5's own messages would go to stderr; the one error says it
    const hid_t f = h.fopen(path.c_str(), 0, 0);
    // libmatio does not check its own H5Fopen: it lists no variables, so a cut file read as an empty one
    // ("holds no real numeric vectors", "has no variable 'ResponseData'")
    if (f < 0) throw Error("'" + path + "' is a MATLAB v7.3 (HDF5) file that HDF5 cannot open: truncated or corrupt");
    Walk w{h, (uint64_t)file_bytes * DEFLATE_MAX_RATIO, (uint64_t)file_bytes, {}, {}, {}, {}, f};
    w.refs_max = (uint64_t)file_bytes / 8;
    h.lvisit(f, H5_INDEX_NAME, H5_ITER_NATIVE, on_link, &w);
    follow_references(w);
    h.fclose(f);
    if (!w.what.empty())
        throw Error(fmt("'%s' variable '%s' %s: corrupt or not a MATLAB file", path.c_str(), w.object.c_str(),
                        w.what.c_str()));
}

}  // namespace msidrec
