"""The batched evaluation of a study at many configurations (jaxbelt.design.configurations): the rows
are padded to whole blocks of one shape, so every block of a chunk size reuses one compilation."""

import numpy as np

from jaxbelt.design import configurations


def test_padded_rows_repeat_the_last_row_up_to_whole_blocks():
    rows = np.arange(10.0).reshape(5, 2)
    out = configurations.padded_rows(rows, 4)
    assert out.shape == (8, 2)
    np.testing.assert_array_equal(out[:5], rows)
    np.testing.assert_array_equal(out[5:], np.repeat(rows[-1:], 3, axis=0))


def test_padded_rows_leave_whole_blocks_and_no_rows_alone():
    rows = np.ones((6, 3))
    assert configurations.padded_rows(rows, 3).shape == (6, 3)
    assert configurations.padded_rows(np.zeros((0, 3)), 4).shape == (0, 3)
