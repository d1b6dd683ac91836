"""Modbus RTU framing for the tests that replay captured frames byte for byte (the drive driver's and the
simulated AZ drive's): the CRC every RTU frame ends with."""


def crc16_modbus(data: bytes) -> bytes:
    """CRC-16/MODBUS (poly 0xA001 reflected, init 0xFFFF), low byte first, as an RTU frame carries it."""
    crc = 0xFFFF
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
    return crc.to_bytes(2, "little")
