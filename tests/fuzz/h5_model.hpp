#pragma once
// A small model of an HDF5 file for the structure-aware harnesses (fuzz_checkpoint,
// fuzz_frames): named entries (datasets and attributes) with a type, a shape and values,
// which the fuzzer's input edits (removes, retypes, reshapes, overwrites with NaN, huge
// or negative numbers, adds) before the model is written with libhdf5 itself. The file
// is therefore always well-formed HDF5: what is fuzzed is our reading and checking of
// its content, not libhdf5's parser (which is not instrumented, and not ours to fix).
#include <fuzzer/FuzzedDataProvider.h>
#include <hdf5.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace softcontact::fuzz {

enum class H5Kind : std::uint8_t { i64, i32, u8, f64, f32, text, vlen_text, count };

struct H5Entry {
  std::string group;           ///< "/", "/run", "/state", ...
  std::string name;
  bool attribute = false;
  H5Kind kind = H5Kind::f64;
  std::vector<hsize_t> dims;   ///< empty: scalar
  std::vector<double> values;  ///< numbers (row-major), converted to `kind` when written
  std::vector<std::int64_t> ints;  ///< exact integers instead of `values` (same size), for integer kinds
  std::string text;            ///< for text kinds; also a char dataset's bytes (kind u8)
  bool unwritten = false;      ///< a dataset created but never written (its extent may be huge)
};

using H5Model = std::vector<H5Entry>;

inline hsize_t element_count(const H5Entry& e) {
  hsize_t n = 1;
  for (hsize_t d : e.dims) n *= d;
  return n;
}

inline std::int64_t saturate(double x) {
  if (std::isnan(x)) return 0;
  if (x >= 9.2e18) return std::numeric_limits<std::int64_t>::max();
  if (x <= -9.2e18) return std::numeric_limits<std::int64_t>::min();
  return static_cast<std::int64_t>(x);
}

inline double special_value(FuzzedDataProvider& in) {
  switch (in.ConsumeIntegralInRange<int>(0, 12)) {
    case 0: return std::numeric_limits<double>::quiet_NaN();
    case 1: return HUGE_VAL;
    case 2: return -HUGE_VAL;
    case 3: return -1;
    case 4: return 0;
    case 5: return 1;
    case 6: return 2147483648.0;
    case 7: return -9.3e18;
    case 8: return 9.3e18;
    case 9: return 1e300;
    case 10: return -2;
    case 11: return static_cast<double>(in.ConsumeIntegral<std::int32_t>());
    default: return in.ConsumeFloatingPoint<double>();
  }
}

/// Applies one edit chosen by the input to `m`. `names` are names an added entry may take.
inline void mutate(H5Model& m, FuzzedDataProvider& in, const std::vector<std::string>& groups,
                   const std::vector<std::string>& names) {
  const int op = in.ConsumeIntegralInRange<int>(0, 6);
  if (m.empty() && op != 5) return;
  H5Entry& e = m[in.ConsumeIntegralInRange<std::size_t>(0, m.empty() ? 0 : m.size() - 1)];
  switch (op) {
    case 0:  // remove
      m.erase(m.begin() + (&e - m.data()));
      break;
    case 1:  // another type
      e.kind = static_cast<H5Kind>(in.ConsumeIntegralInRange<int>(0, static_cast<int>(H5Kind::count) - 1));
      break;
    case 2: {  // another shape: rank 0..3, extents near the old ones (at most 4096), values kept or padded
      const int rank = in.ConsumeIntegralInRange<int>(0, 3);
      std::vector<hsize_t> dims;
      for (int d = 0; d < rank; ++d) {
        const hsize_t old =
            std::min<hsize_t>(4096, d < static_cast<int>(e.dims.size()) ? e.dims[static_cast<std::size_t>(d)] : 1);
        dims.push_back(static_cast<hsize_t>(std::max<long long>(0, static_cast<long long>(old) + in.ConsumeIntegralInRange<int>(-2, 2))));
      }
      e.dims = dims;
      e.values.resize(std::min<hsize_t>(element_count(e), hsize_t{1} << 20), 0.0);
      e.ints.clear();
      e.unwritten = false;
      break;
    }
    case 3: {  // overwrite values
      const int k = in.ConsumeIntegralInRange<int>(1, 4);
      for (int j = 0; j < k && !e.values.empty(); ++j) {
        const std::size_t i = in.ConsumeIntegralInRange<std::size_t>(0, e.values.size() - 1);
        e.values[i] = special_value(in);
        if (i < e.ints.size()) e.ints[i] = saturate(e.values[i]);
      }
      if (e.values.empty() && e.dims.empty()) e.values.push_back(special_value(in));
      break;
    }
    case 4:  // other text (also a char dataset's bytes)
      e.text = in.ConsumeRandomLengthString(256);
      break;
    case 5: {  // a new entry
      H5Entry n;
      n.group = groups[in.ConsumeIntegralInRange<std::size_t>(0, groups.size() - 1)];
      n.name = names[in.ConsumeIntegralInRange<std::size_t>(0, names.size() - 1)];
      n.attribute = in.ConsumeBool();
      n.kind = static_cast<H5Kind>(in.ConsumeIntegralInRange<int>(0, static_cast<int>(H5Kind::count) - 1));
      const int rank = in.ConsumeIntegralInRange<int>(0, 2);
      for (int d = 0; d < rank; ++d) n.dims.push_back(in.ConsumeIntegralInRange<hsize_t>(0, 8));
      n.values.assign(element_count(n), special_value(in));
      m.push_back(n);
      break;
    }
    default: {  // a dataset whose extent claims far more than the file holds
      if (e.attribute) break;
      if (e.dims.empty()) e.dims.push_back(1);
      e.dims[0] = hsize_t{1} << in.ConsumeIntegralInRange<int>(20, 40);
      e.values.clear();
      e.ints.clear();
      e.unwritten = true;
      break;
    }
  }
}

namespace detail {

inline hid_t file_type(H5Kind k, std::size_t text_size) {
  switch (k) {
    case H5Kind::i64: return H5Tcopy(H5T_STD_I64LE);
    case H5Kind::i32: return H5Tcopy(H5T_STD_I32LE);
    case H5Kind::u8: return H5Tcopy(H5T_STD_I8LE);
    case H5Kind::f64: return H5Tcopy(H5T_IEEE_F64LE);
    case H5Kind::f32: return H5Tcopy(H5T_IEEE_F32LE);
    case H5Kind::text: {
      const hid_t t = H5Tcopy(H5T_C_S1);
      H5Tset_size(t, text_size + 1);
      return t;
    }
    default: {
      const hid_t t = H5Tcopy(H5T_C_S1);
      H5Tset_size(t, H5T_VARIABLE);
      return t;
    }
  }
}

inline hid_t ensure_group(hid_t file, const std::string& group) {
  if (group == "/") return H5Gopen2(file, "/", H5P_DEFAULT);
  if (H5Lexists(file, group.c_str(), H5P_DEFAULT) > 0) return H5Gopen2(file, group.c_str(), H5P_DEFAULT);
  return H5Gcreate2(file, group.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
}

}  // namespace detail

/// Writes every entry of `m` into the open file (entries that libhdf5 refuses, such as a
/// second entry of one name, are left out). Returns nothing: what was written is what
/// the reader gets.
inline void write_model(hid_t file, const H5Model& m) {
  for (const H5Entry& e : m) {
    const hid_t g = detail::ensure_group(file, e.group);
    if (g < 0) continue;
    const hsize_t n = element_count(e);
    const hid_t space = e.dims.empty() ? H5Screate(H5S_SCALAR)
                                       : H5Screate_simple(static_cast<int>(e.dims.size()), e.dims.data(), nullptr);
    const bool text = e.kind == H5Kind::text || e.kind == H5Kind::vlen_text;
    const hid_t type = detail::file_type(e.kind, e.text.size());
    const hid_t obj = e.attribute ? H5Acreate2(g, e.name.c_str(), type, space, H5P_DEFAULT, H5P_DEFAULT)
                                  : H5Dcreate2(g, e.name.c_str(), type, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    if (obj >= 0 && !e.unwritten && n <= (text ? hsize_t{4096} : hsize_t{1} << 20)) {
      herr_t status = 0;
      if (text) {
        // Every element the same text.
        std::vector<std::string> copies(n, e.text);
        if (e.kind == H5Kind::text) {
          std::string buf;
          for (const auto& c : copies) buf.append(c.c_str(), c.size() + 1);
          status = e.attribute ? H5Awrite(obj, type, buf.data()) : H5Dwrite(obj, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, buf.data());
        } else {
          std::vector<const char*> ptrs(n, e.text.c_str());
          status = e.attribute ? H5Awrite(obj, type, ptrs.data())
                               : H5Dwrite(obj, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, ptrs.data());
        }
      } else if (e.kind == H5Kind::u8 && !e.text.empty()) {
        std::vector<char> buf(n, 0);
        for (hsize_t i = 0; i < n && i < e.text.size(); ++i) buf[i] = e.text[i];
        status = e.attribute ? H5Awrite(obj, H5T_NATIVE_CHAR, buf.data())
                             : H5Dwrite(obj, H5T_NATIVE_CHAR, H5S_ALL, H5S_ALL, H5P_DEFAULT, buf.data());
      } else if ((e.kind == H5Kind::i64 || e.kind == H5Kind::i32 || e.kind == H5Kind::u8) && e.ints.size() == n) {
        status = e.attribute ? H5Awrite(obj, H5T_NATIVE_INT64, e.ints.data())
                             : H5Dwrite(obj, H5T_NATIVE_INT64, H5S_ALL, H5S_ALL, H5P_DEFAULT, e.ints.data());
      } else {
        // Numbers go through double; libhdf5 converts (clipping what does not fit).
        std::vector<double> buf(n, 0.0);
        for (hsize_t i = 0; i < n && i < e.values.size(); ++i) buf[i] = e.values[i];
        status = e.attribute ? H5Awrite(obj, H5T_NATIVE_DOUBLE, buf.data())
                             : H5Dwrite(obj, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, buf.data());
      }
      (void)status;
    }
    if (obj >= 0) e.attribute ? H5Aclose(obj) : H5Dclose(obj);
    H5Tclose(type);
    H5Sclose(space);
    H5Gclose(g);
  }
}

inline H5Entry scalar_attribute(const std::string& group, const std::string& name, H5Kind kind, double value) {
  H5Entry e;
  e.group = group;
  e.name = name;
  e.attribute = true;
  e.kind = kind;
  e.values = {value};
  if (kind == H5Kind::i64 || kind == H5Kind::i32) e.ints = {saturate(value)};
  return e;
}

inline H5Entry text_attribute(const std::string& group, const std::string& name, const std::string& text) {
  H5Entry e;
  e.group = group;
  e.name = name;
  e.attribute = true;
  e.kind = H5Kind::text;
  e.text = text;
  return e;
}

inline H5Entry dataset(const std::string& group, const std::string& name, H5Kind kind, std::vector<hsize_t> dims,
                       std::vector<double> values) {
  H5Entry e;
  if (kind == H5Kind::i64 || kind == H5Kind::i32)
    for (double v : values) e.ints.push_back(saturate(v));
  e.group = group;
  e.name = name;
  e.kind = kind;
  e.dims = std::move(dims);
  e.values = std::move(values);
  return e;
}

}  // namespace softcontact::fuzz
