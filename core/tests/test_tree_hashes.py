"""The trees of every method stay bit-identical across refactorings of the
builders: the sha256 of each tree's node and plane arrays and its SAH cost on
two generated scenes (and on `room` with clipped leaf boxes, whose leaves are
laid out differently), recorded on main before the cost model and the named
node kinds (core/src/cost_model.hpp, Node in tree.hpp) replaced the inline
formulas and bare kind bits. A change that moves one plane or rounds one cost
differently changes a hash here.

A deliberate change of the trees (a new cost term, another tie rule) updates
this table: print the new values with `python core/tests/test_tree_hashes.py`
and say in the commit why the trees changed."""

import hashlib

import pytest

import bsplab
from bsplab import scenes

# "scene/method[/option=value]": (sha256 of node_bytes(), stats["sah_cost"]).
RECORDED = {
    "room/kd": ("753c2ac9d09187ba4c534f20836a36ba9eeea91662187bb56d6018820ba74dfe", 36.87647837804136),
    "room/rbsp": ("7422e664096618878cc4d01ea5adbd4475a111d398b16f3be4b5e7a4448e6fc5", 35.61892043352276),
    "room/rbsp+kd": ("ff74b211abc43e61d5c12ea68317ddd243bb416cafd86d8930c8c854ba4d5e32", 36.0087087205346),
    "room/bsp_random": ("bbd1f45287ea648734488482b1b7dbdb00d3a9a6c2f63f96f4bc6896f16c41bd", 82.72295106359672),
    "room/bsp_random+": ("585341c8f51f9aceb74a464cde2bf5325e84e9fe4441ce4358452eefa3b74864", 35.61040240703397),
    "room/bsp_random+kd": ("33195daf1eb1495c0319cc707886863d243d31f492439f29232a990973a4b1a5", 35.64365411755975),
    "room/bsp_wn": ("dc98929dc24989199b1629a7f64ac6f2e93751337153888ea548115b1ffc9bf7", 121.74922903675213),
    "room/bsp_wn+": ("afd8565ac62d158b5bdef53d1287b2fd15b2e34a49f43d33d5359ff22a5bf05d", 35.13032062786454),
    "room/bsp_wn+kd": ("cc5eb474f0d1f83746ce3da4485d2258678676d5f9bdf5676c0688bc83851d6c", 35.57326948220246),
    "room/bsp_cn": ("d5508f1a312675394f1f428b4337444864fbf5c8b2afe11567e470cf029a5469", 155.04878281005713),
    "room/bsp_cn+": ("facf33bfa570b9ef508165edcdf6be098a818a90506d572b046bcd3e27e41fb2", 35.147949902225136),
    "room/bsp_cn+kd": ("abd100f3bba13917935f0fb589c61c197df56cecc81119eb2f93b8c15feaa665", 35.58175023283299),
    "room/bsp_ize": ("dfba5b17e2d81a202c4ba3a38b9be4a87d3d218dadaf732de33d623d72161f18", 35.01541896412897),
    "room/bsp_ize+kd": ("de4d799c73fc443af16d08115e7bd11b8e24ed06f63a9a3b65f2ff82cf9c281c", 35.70470298510913),
    "fan/kd": ("86a8a9a9b06a2440aae2d686379c312f6432d5e1d701857f7f5d0696e2488f69", 160.68277924179563),
    "fan/rbsp": ("b835e61b2d0eb85585e29a96fc99453ea23a72350a37067411e2e3fedbeff980", 417.99806267711074),
    "fan/rbsp+kd": ("a445be359be92ce59d048954d9d2694011b9999a36a8768f93a6868774aa8e12", 451.4715723807821),
    "fan/bsp_random": ("ee20056795fb762dd1c883bc7327bd14a1dfaf1e2bc82f175e4337d4bc900fca", 8003.416747792928),
    "fan/bsp_random+": ("795f6d4b0a01a1a989d616bdc157b0a7670e14cb2ac5ee011e107ed0a79c1173", 261.2587212629203),
    "fan/bsp_random+kd": ("fc79803230867c03eec0a6d39bfaba4b9f83b619e392bcf12d7f609e9e7b190c", 412.65964036410884),
    "fan/bsp_wn": ("b18022811a9ffbb79445ebc1ca612375b5f6f842179cc8a9ea0b67b76bbc593e", 1769.1254515338542),
    "fan/bsp_wn+": ("23139da337c2f4430c9b2b2c7f8d54b6a40f13752b6a232715e20d6ec703af96", 495.73528656451623),
    "fan/bsp_wn+kd": ("da480902e955a434b5d2487cd226aaf4db7c6122082fa075808d257cb5bb546b", 482.409546219565),
    "fan/bsp_cn": ("02e3591542223787759f1b429326f8013a4a8382e75d18fd777e496e7575b7b6", 411.42439332846834),
    "fan/bsp_cn+": ("02013255dd0c5732cb3dc799f4a26a44d33524b715d863be38ad2d9abdbd8e98", 383.4751727658886),
    "fan/bsp_cn+kd": ("1e76ba95e73a6196e1b01c2664a6ef18d03b91d542e094dfbd27127daf837fcc", 482.5446472316018),
    "fan/bsp_ize": ("44924cab730d8bb514153733c313b0824e0ba65c121feb306351a2c870ffbf01", 259.16923971853527),
    "fan/bsp_ize+kd": ("f74842277588d303e6bdf17828e0efe3a4970e1a16bd073bad40fa40815177d9", 484.31108090655425),
    "room/kd/leaf_boxes=clipped": ("ca55e1b8bc9cf67a71fa92ee2201e17573d93625e3ec80fc339095fb78fcf0ce", 36.87647837804136),
    "room/rbsp/leaf_boxes=clipped": ("2c091451e1c44eedbb072a5f4a1238a1882b4bcd9d25568482e7f6ed1ca8cdce", 35.61892043352276),
    "room/rbsp+kd/leaf_boxes=clipped": ("12f79ab9cfb42fcb544a26b19e1e2d2858f80c31dd72ff92f41bb3cb9c3c60db", 36.0087087205346),
    "room/bsp_random/leaf_boxes=clipped": ("269e0eb49087676e8c7c4152a8d61daf5429f3f4381dc5bd96762ce4c84d0e3f", 82.72295106359672),
    "room/bsp_random+/leaf_boxes=clipped": ("985333ea379e57531ca4adf2f7badc3bcd139f9dced7d69b1528d8a2543abe6e", 35.61040240703397),
    "room/bsp_random+kd/leaf_boxes=clipped": ("c4e2c516ef9a9b37f29e674f7bd1ca52e32a9c1faa2a8b1eb14543ea6013d8d3", 35.64365411755975),
    "room/bsp_wn/leaf_boxes=clipped": ("f74edccad06121aae02ef391a067150d06fad2b6b0d82faa09ee0a5643d4e9b7", 121.74922903675213),
    "room/bsp_wn+/leaf_boxes=clipped": ("0fa1df7af3ce125204ef686944229c68c262986bf91a5ef228058d323e0ea75b", 35.13032062786454),
    "room/bsp_wn+kd/leaf_boxes=clipped": ("2745f900f18aff6e11f40e68c0747c9dce3e1146de30174a708eaa18fe8313e4", 35.57326948220246),
    "room/bsp_cn/leaf_boxes=clipped": ("b16b4bf638aabe6ea8b9696d6dfae06b61878c91971e989e0635ac18246a1648", 155.04878281005713),
    "room/bsp_cn+/leaf_boxes=clipped": ("50773b128e79ca62e202e7689e0ad48123a98407e0502810acfc5e9256b4c271", 35.147949902225136),
    "room/bsp_cn+kd/leaf_boxes=clipped": ("22151272a233eeaa6373e7d7230b9c0c61bcc79f142f8d4b27d82d7ebf2bb43a", 35.58175023283299),
    "room/bsp_ize/leaf_boxes=clipped": ("756ecd9e8badadee2d452e9780353923f5d43d75d3821890f57246c6644d505a", 35.01541896412897),
    "room/bsp_ize+kd/leaf_boxes=clipped": ("1274cdd5fad2df436cb9a749702d8a3a70cb0dcc58bd0aac73d7f919d36a2018", 35.70470298510913),
}


# The scenes and options each method is recorded on.
CASES = (("room", ""), ("fan", ""), ("room", "/leaf_boxes=clipped"))


def _case(key: str):
    scene, method, *extra = key.split("/")
    return scene, method, dict(e.split("=", 1) for e in extra)


def _measure(key: str):
    scene, method, options = _case(key)
    tree = bsplab.build(scenes.generate(scene), method, **options)
    return hashlib.sha256(tree.node_bytes()).hexdigest(), tree.stats["sah_cost"]


def test_every_method_is_recorded():
    # A new method gets a recorded tree too (run this file as a script).
    want = {f"{scene}/{m}{extra}" for scene, extra in CASES for m in bsplab.methods()}
    assert set(RECORDED) == want


@pytest.mark.parametrize("key", sorted(RECORDED))
def test_tree_is_bit_identical(key):
    digest, sah_cost = _measure(key)
    want_digest, want_cost = RECORDED[key]
    assert sah_cost == want_cost, f"{key}: SAH cost {sah_cost!r}, recorded {want_cost!r}"
    assert digest == want_digest, f"{key}: the tree's bytes changed (same SAH cost)"


if __name__ == "__main__":
    for scene, extra in CASES:
        for method in bsplab.methods():
            key = f"{scene}/{method}{extra}"
            digest, cost = _measure(key)
            print(f'    "{key}": ("{digest}", {cost!r}),')
