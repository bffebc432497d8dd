// The registry (registry.hpp) as plain dicts and lists: what the Python
// package generates its method table, option checks and the add-on's panel
// from; and options_for(), the BuildOptions a method's values make, and
// top_settings_for(), the TopLevelSettings the top options make (for the
// registry's tests: a build goes through tree.cpp's build() and an instanced
// one through instanced.cpp's build_instanced() in one call).
#include <nanobind/nanobind.h>
#include <nanobind/stl/map.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/variant.h>
#include <nanobind/stl/vector.h>

#include "bindings/bindings.hpp"
#include "instanced.hpp"
#include "registry.hpp"

namespace bsp::bindings {

namespace nb = nanobind;
using namespace nb::literals;

namespace {

nb::object value(const OptionValue& v) {
    return std::visit([](const auto& x) -> nb::object { return nb::cast(x); }, v);
}

nb::object optional_value(const std::optional<OptionValue>& v) {
    return v ? value(*v) : nb::none();
}

nb::dict option_dict(const OptionSpec& o) {
    static const char* types[] = {"float", "int", "enum"};
    nb::dict d;
    d["name"] = o.name;
    d["type"] = types[int(o.type)];
    d["group"] = o.group;
    d["default"] = value(o.default_value);
    d["min"] = optional_value(o.min);
    d["max"] = optional_value(o.max);
    d["min_open"] = o.min_open;
    d["per_method_limits"] = o.per_method_limits;
    d["soft_max"] = o.soft_max ? nb::cast(*o.soft_max) : nb::none();
    nb::list choices;
    for (const Choice& c : o.choices) {
        nb::dict cd;
        cd["name"] = c.name;
        cd["label"] = c.label;
        cd["help"] = c.help;
        cd["k_values"] = c.k_values;
        choices.append(cd);
    }
    d["choices"] = choices;
    d["label"] = o.label;
    d["short_label"] = o.short_label;
    d["help"] = o.help;
    d["field"] = o.field;
    return d;
}

nb::dict method_dict(const MethodSpec& m) {
    nb::dict d;
    d["name"] = m.name;
    d["label"] = m.label;
    d["description"] = m.description;
    d["builder"] = m.builder.name;
    d["structure"] = structure_name(m.builder.structure);
    d["all_general_nodes"] = m.all_general_nodes();
    d["strategy"] = m.strategy;
    d["plus_axes"] = m.plus_axes;
    d["kd_nodes"] = m.kd_nodes;
    d["options"] = m.options;
    nb::dict defaults;
    for (const auto& [name, v] : m.defaults) defaults[name.c_str()] = value(v);
    d["defaults"] = defaults;
    d["min_k"] = m.min_k();
    d["max_k"] = m.max_k();
    return d;
}

nb::dict registry() {
    nb::dict d;
    nb::list options, methods;
    for (const OptionSpec& o : option_specs()) options.append(option_dict(o));
    for (const MethodSpec& m : method_specs()) methods.append(method_dict(m));
    d["options"] = options;
    d["methods"] = methods;
    d["strategies"] = strategy_names();
    d["max_k"] = kMaxK;
    return d;
}

}  // namespace

void bind_registry(nb::module_& m) {
    nb::enum_<LeafBoxes>(m, "LeafBoxes")
        .value("none", LeafBoxes::None)
        .value("triangle", LeafBoxes::Triangle)
        .value("clipped", LeafBoxes::Clipped);

    nb::enum_<BuildQuality>(m, "BuildQuality")
        .value("exact", BuildQuality::Exact)
        .value("fast", BuildQuality::Fast);

    nb::class_<BuildOptions>(m, "BuildOptions")
        .def(nb::init<>())
        .def_rw("traversal_cost", &BuildOptions::traversal_cost)
        .def_rw("intersect_cost", &BuildOptions::intersect_cost)
        .def_rw("empty_bonus", &BuildOptions::empty_bonus)
        .def_rw("max_depth", &BuildOptions::max_depth)
        .def_rw("leaf_size", &BuildOptions::leaf_size)
        .def_rw("max_duplication", &BuildOptions::max_duplication)
        .def_rw("memory_limit_mb", &BuildOptions::memory_limit_mb)
        .def_rw("threads", &BuildOptions::threads)
        .def_rw("strategy", &BuildOptions::strategy)
        .def_rw("k", &BuildOptions::k)
        .def_rw("plus_axes", &BuildOptions::plus_axes)
        .def_rw("kd_nodes", &BuildOptions::kd_nodes)
        .def_rw("bins", &BuildOptions::bins)
        .def_rw("fixed_set", &BuildOptions::fixed_set)
        .def_rw("seed", &BuildOptions::seed)
        .def_rw("alpha", &BuildOptions::alpha)
        .def_rw("general_cost", &BuildOptions::general_cost)
        .def_rw("cluster_iterations", &BuildOptions::cluster_iterations)
        .def_rw("cluster_sample", &BuildOptions::cluster_sample)
        .def_rw("ize_candidates", &BuildOptions::ize_candidates)
        .def_rw("leaf_boxes", &BuildOptions::leaf_boxes)
        .def_rw("build_quality", &BuildOptions::build_quality)
        .def_rw("fast_bins", &BuildOptions::fast_bins)
        .def_rw("fast_min_refs", &BuildOptions::fast_min_refs)
        .def_rw("fast_min_gain", &BuildOptions::fast_min_gain)
        .def_rw("fast_clip_min_refs", &BuildOptions::fast_clip_min_refs);

    m.def("registry", &registry, "The methods, options and strategies of registry.hpp.");
    m.def(
        "options_for",
        [](const std::string& method, const std::map<std::string, OptionValue>& values) {
            return options_for(method_spec(method), values);
        },
        "method"_a, "values"_a, "The method's BuildOptions with `values` set by option name.");

    nb::class_<TopLevelSettings>(m, "TopLevelSettings")
        .def(nb::init<>())
        .def_rw("bins", &TopLevelSettings::bins)
        .def_rw("traversal_cost", &TopLevelSettings::traversal_cost)
        .def_rw("intersect_cost", &TopLevelSettings::intersect_cost)
        .def_rw("threads", &TopLevelSettings::threads);
    m.def("top_settings_for", &top_settings_for, "values"_a,
          "The top level's settings with `values` (the top options, threads) set by name.");
}

}  // namespace bsp::bindings
