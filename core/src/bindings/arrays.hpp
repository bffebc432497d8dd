// The array types the bindings take from numpy, and handing a C++ vector to
// numpy without a copy: shared by the binding files of every area.
#pragma once
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>

#include <cstddef>
#include <vector>

namespace bsp::bindings {

namespace nb = nanobind;

using TriArray = nb::ndarray<const float, nb::shape<-1, 3, 3>, nb::c_contig, nb::device::cpu>;
using Vec3Array = nb::ndarray<const float, nb::shape<-1, 3>, nb::c_contig, nb::device::cpu>;
using FloatIn = nb::ndarray<const float, nb::ndim<1>, nb::c_contig, nb::device::cpu>;
template <class T>
using Out = nb::ndarray<T, nb::ndim<1>, nb::c_contig, nb::device::cpu>;

// A vector handed to numpy without a copy: the array owns it from here on.
template <class T>
nb::ndarray<nb::numpy, T> owned_array(std::vector<T>&& v, size_t columns = 1) {
    auto* owner = new std::vector<T>(std::move(v));
    nb::capsule free_it(owner, [](void* p) noexcept { delete static_cast<std::vector<T>*>(p); });
    const size_t rows = owner->size() / columns;
    if (columns == 1) return nb::ndarray<nb::numpy, T>(owner->data(), {rows}, free_it);
    return nb::ndarray<nb::numpy, T>(owner->data(), {rows, columns}, free_it);
}

}  // namespace bsp::bindings
